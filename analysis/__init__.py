"""cutlab.analysis: cutting mechanics and identification.

The lowest of cutlab's three packages: force models (face mill with ploughing, end mills with edge
forces), coefficient fitting, feed-rule derivation, modal identification, the run-file layout and
the validated configs that every package shares. It imports nothing of ``planning`` or ``rig``.
"""

__version__ = "0.1.0"
