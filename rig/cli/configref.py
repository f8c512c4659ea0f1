"""``python -m rig.cli.configref [--check]``: writes docs/configuration.md (rig.configref)."""

import sys

from rig.configref import main

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
