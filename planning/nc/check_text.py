"""What ``cutlab nc check`` prints: the summary as quantity / value rows, and the answer when
the controller of ``--dialect`` refuses a line (its reading of the program stops there)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from analysis.output import table_lines
from planning.nc.check import ProgramSummary, check_program, dialect_problems
from planning.nc.dialect import DialectProblem
from planning.nc.errors import NCError

__all__ = ["CheckAnswer", "check_answer", "refused_summary", "summary_rows"]


@dataclass(frozen=True)
class CheckAnswer:
    """``cutlab nc check``'s answer: the summary (or the refusals, when the controller refuses a
    line), and its exit status (2: a line refused)."""

    summary: ProgramSummary | dict[str, object]
    refused: bool
    code: int

    def lines(self) -> list[str]:
        """The summary as a quantity / value table (nothing when refused: the notes said it)."""
        return [] if self.refused else table_lines(summary_rows(self.summary))


def check_answer(
    file: str, machine: str | None = None, dialect: str | None = None, *, strict: bool = True,
    progress: Callable[[float, float], None] | None = None,
    note: Callable[[str], None] = lambda message: None,
) -> CheckAnswer:  # fmt: skip
    """The program ``file`` checked (:func:`~planning.nc.check.check_program`) and, with
    ``dialect``, what that controller would refuse in it; the refusals and warnings go to
    ``note`` one line each, in order."""
    problems = dialect_problems(file, dialect) if dialect else None
    for p in problems or ():
        note(f"{p.severity}: {p}")
    refused = sum(p.severity == "error" for p in problems or ())
    try:
        run = check_program(file, machine, strict=strict, progress=progress, dialect=dialect)
    except NCError as exc:
        if not refused:
            raise
        # the controller refuses a line, so its reading of the program stops there: the
        # refusals are the answer, and the summary is not made
        note(f"{file}: {dialect} would refuse {refused} line(s)")
        return CheckAnswer(refused_summary(file, str(dialect), problems or (), str(exc)), True, 2)
    for w in run.warnings:
        note(f"warning: {w}")
    out = run.summary()
    if dialect and problems is not None:
        out["dialect"] = dialect
        out["dialect_problems"] = [p.as_dict() for p in problems]
    if refused:
        note(f"{file}: {dialect} would refuse {refused} line(s)")
    for w in out["warnings"][len(run.warnings) :]:  # the machine's travel limits
        note("warning: " + w)
    return CheckAnswer(out, False, 2 if refused else 0)

#: summary keys that are not one row each (the bbox and rotary ranges are split, the warnings
#: and refusals go to stderr)
_NOT_ROWS = ("bbox", "warnings", "rotary_range_deg", "dialect_problems")


def summary_rows(out: Mapping[str, object]) -> list[dict[str, object]]:
    """:meth:`CheckedProgram.summary` as rows: each quantity, the rotary ranges (deg), then the
    bbox corners (mm), 4 significant digits."""
    rows: list[dict[str, object]] = [{"quantity": k, "value": v} for k, v in out.items()
                                     if k not in _NOT_ROWS and v is not None]  # fmt: skip
    rotary, bbox = out.get("rotary_range_deg", {}), out["bbox"]
    assert isinstance(rotary, Mapping) and isinstance(bbox, Mapping)
    for c, (lo, hi) in rotary.items():
        rows.append({"quantity": f"{c}_range_deg", "value": f"{lo:.4g} {hi:.4g}"})
    for end in ("min", "max"):
        xyz = " ".join(f"{c:.4g}" for c in bbox[f"{end}_mm"])
        rows.append({"quantity": f"bbox_{end}_mm", "value": xyz})
    return rows


def refused_summary(
    file: str, dialect: str, problems: Sequence[DialectProblem], reason: str
) -> dict[str, object]:
    """``nc check --json`` when the controller refuses a line: the refusals are the answer, and
    no summary is made (``summary_reason`` says why)."""
    return {"file": file, "dialect": dialect, "dialect_problems": [p.as_dict() for p in problems],
            "summary": None, "summary_reason": reason}  # fmt: skip
