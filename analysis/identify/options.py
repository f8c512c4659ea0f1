"""How exports and run files are read for a fit or an import (:class:`ImportOptions`): the axis
mapping, the conditions table and file-name pattern, the offset, the user's catalogues. Its own
light module (the fitting code loads when the options are used): the CLI declares `analyze forces`
and `data import`'s options from its fields when it builds its parser."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from analysis.identify.axes import AxisMap
    from analysis.identify.conditions import ConditionsTable

__all__ = ["ImportOptions"]


@dataclass(frozen=True)
class ImportOptions:
    """How to read each file: ``axes`` (``x=-Fy,y=Fx,z=-Fz`` or None for the rig config's /
    the files' own), a conditions ``table`` (path or loaded), a file-name ``pattern``, a
    ``zero_file`` or ``zeroed`` (exports), the user's ``tools_path`` and ``materials_path``."""

    # the metadata: the options of `cutlab analyze forces` and `data import` (rig.cli.options)
    axes: AxisMap | str | None = field(default=None, metadata={
        "metavar": "x=COL,y=COL,z=COL",
        "help": "file columns (or run-file channels) for cutlab's x (feed), y (cross-feed), z "
        "(tool axis), a '-' flips the sign: x=-Fy,y=Fx,z=-Fz; or 'auto': the signed permutation "
        "whose end-mill fit gives positive Ktc, Krc, Kac with the smallest residual (refused "
        "when the runs cannot tell; slots alone cannot tell x from y) (default: the rig config's "
        "dynamometer, else columns named Fx, Fy, Fz; a mapping giving a negative cutting "
        "coefficient or fitting clearly worse than another is refused)"})
    table: ConditionsTable | str | Path | None = None
    pattern: str | None = field(default=None, metadata={
        "flag": "--conditions-pattern", "metavar": "PATTERN", "help":
        "conditions from file names: 'cut_{spindle_rpm}rpm_f{feed_mm_min}.txt'"})
    zero_file: str | Path | None = field(default=None, metadata={"flag": "--zero",
        "metavar": "FILE", "help":
        "an export of the same channels at rest: its mean is the offset"})
    zeroed: bool = field(default=False, metadata={
        "help": "the exports are already zeroed: subtract no offset"})
    tools_path: str | Path | None = field(default=None, metadata={"metavar": "FILE", "help":
        "your tool catalogue (TOML, [tools.NAME]), before configs/tools.toml"})
    materials_path: str | Path | None = field(default=None, metadata={"metavar": "FILE", "help":
        "your material catalogue (TOML), before configs/materials.toml"})

    @property
    def auto(self) -> bool:
        """``--axes auto``: the mapping is chosen from the fit
        (:func:`analysis.identify.axes.choose_axes`)."""
        return isinstance(self.axes, str) and self.axes.strip().lower() == "auto"

    def loaded(self) -> ImportOptions:
        """Parsed once: the mapping and the table (``auto`` stays ``"auto"``)."""
        from analysis.identify.axes import parse_axes
        from analysis.identify.conditions import ConditionsTable, load_conditions_table

        axes = self.axes
        if isinstance(axes, str) and not self.auto:
            axes = parse_axes(axes)
        table = self.table
        if table is not None and not isinstance(table, ConditionsTable):
            table = load_conditions_table(table)
        return ImportOptions(axes, table, self.pattern, self.zero_file, self.zeroed,
                             self.tools_path, self.materials_path)  # fmt: skip

    def layers(self, path: str | Path) -> list[tuple[str, Mapping[str, object]]]:
        """The conditions from the table row and the file-name pattern of ``path``."""
        from analysis.identify.conditions import ConditionsTable, pattern_conditions

        out: list[tuple[str, Mapping[str, object]]] = []
        if isinstance(self.table, ConditionsTable):
            out.append(self.table.row(path))
        if self.pattern:
            out.append((f"{Path(str(path)).name} (--conditions-pattern)",
                        pattern_conditions(self.pattern, path)))  # fmt: skip
        return out
