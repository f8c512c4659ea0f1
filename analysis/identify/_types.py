"""Types the identification's modules share (a statistics row, the options a synthetic run passes
on, a progress callback, a fit result) and :func:`with_rejected` on a fit result."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import Field, replace
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, TypedDict, TypeVar

import numpy as np

if TYPE_CHECKING:
    from analysis.modal import DynamometerFilter

#: Called with the samples read since the last call (a run file streamed).
Progress = Callable[[int], None]
#: A statistics row of a fit's coefficient: value, std_error, ci_low... (floats), identified
#: (bool), status (text).
StatsRow = dict[str, float | bool | str]


class SyntheticOptions(TypedDict, total=False):
    """The keyword options of :func:`analysis.identify._common.synthetic_run` the model-specific
    ones pass on."""

    air_s: float
    noise_frac: float
    dynamometer: DynamometerFilter | None
    rng: np.random.Generator | None
    offset_n: Sequence[float]
    drift_n_s: Sequence[float]
    phase_rad: float
    oversample: int


class FitResult(Protocol):
    """A fit result: a frozen dataclass with a ``message`` (and ``rejected``)."""

    # dataclasses.replace takes dataclasses: the fields' table (typeshed's DataclassInstance)
    __dataclass_fields__: ClassVar[dict[str, Field[Any]]]

    @property
    def message(self) -> str: ...


FitT = TypeVar("FitT", bound=FitResult)


def with_rejected(fit: FitT, rejected: Sequence[tuple[str, str]]) -> FitT:
    """A fit result (frozen dataclass with ``message`` and ``rejected``) naming rejected runs."""
    if not rejected:
        return fit
    why = "; ".join(f"{n}: {m}" for n, m in rejected)
    msg = f"{fit.message} (rejected {len(rejected)} run(s): {why})"
    return replace(fit, message=msg, rejected=tuple(rejected))
