"""The force-model protocol and its registry: one :class:`ForceModel` per cutter class, found by
:func:`model_for` (the tool) or :func:`model_named` (``--model facemill|endmill``).

What the twin, the planners, the limits and the identification ask of a force model:

- ``forces`` / ``design`` / ``mean_design``: the workpiece force of an engagement (a cut), the
  regressors of its linear parameters, their per-revolution mean;
- ``cut``: the engagement from a run's geometry (feed per tooth, depth, width, mode, offset);
- the identification design: ``parameters`` (the fit's linear parameters), ``edge_keys`` (the
  coefficients a run set identifies only when its feeds separate edge forces from cutting forces)
  and :meth:`ForceModel.identifiable` (which coefficients runs at these feeds can identify);
- the catalogue schema: ``tool_schema`` (the fields a tool of that class carries) and
  ``coefficients_schema`` (the material's table, ``[materials.NAME.<name>]``).

This module is the only place that tests a tool's class (tests/test_layers.py says so): a new
cutter class is one implementation here and one entry in ``MODELS``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal, Protocol, TypeGuard, TypeVar, runtime_checkable

import numpy as np
import numpy.typing as npt
from numpy.typing import ArrayLike
from pydantic import BaseModel as Model

from analysis.config import (
    EndMill,
    EndMillCoefficients,
    FaceMill,
    FaceMillCoefficients,
    Material,
)
from analysis.errors import AnalysisError
from analysis.forces import endmill as _em
from analysis.forces import facemill as _fm

__all__ = [
    "ENDMILL",
    "FACEMILL",
    "Coefficients",
    "Cut",
    "CutConditions",
    "ForceModel",
    "MODELS",
    "ModelTool",
    "model_for",
    "model_named",
]

#: A tool some model describes, the engagement and the coefficients of one (the protocol's
#: arguments; each model narrows them to its own class and refuses another).
ModelTool = FaceMill | EndMill
Cut = _fm.FaceMillCut | _em.EndMillCut
Coefficients = FaceMillCoefficients | EndMillCoefficients
Array = npt.NDArray[np.float64]

_T = TypeVar("_T")


class CutConditions(Protocol):
    """What :meth:`ForceModel.cut` reads of a run's conditions (mm, deg)."""

    @property
    def fz_mm(self) -> float: ...
    @property
    def depth_mm(self) -> float: ...
    @property
    def width_mm(self) -> float: ...
    @property
    def center_offset_mm(self) -> float: ...
    @property
    def mode(self) -> str: ...
    @property
    def feed_angle_deg(self) -> float: ...

#: Distinct feeds per tooth a run set needs before its edge (ploughing) terms can be identified.
EDGE_FEEDS = 3

#: Rotation angles of a face mill's per-revolution mean (the identification's grid).
_FACEMILL_MEAN_ANGLES = 4096


@runtime_checkable
class ForceModel(Protocol):
    """A cutting-force model of one cutter class (see module docstring)."""

    @property
    def name(self) -> str: ...  # "facemill" | "endmill": the material's table, ``--model``
    @property
    def label(self) -> str: ...  # for messages: "face mill", "end mill"
    @property
    def tool_schema(self) -> type[Model]: ...  # the catalogue's fields of such a tool
    @property
    def coefficients_schema(self) -> type[Model]: ...  # the material's table
    @property
    def parameters(self) -> tuple[str, ...]: ...  # the linear parameters, columns of ``design``
    @property
    def edge_keys(self) -> tuple[str, ...]: ...  # coefficients of the edge (ploughing) terms

    def teeth(self, tool: ModelTool) -> int: ...
    def cut(self, tool: ModelTool, conditions: CutConditions) -> Cut: ...
    def design(
        self, phi_rad: ArrayLike, tool: ModelTool, cut: Cut, n_discs: int = 24
    ) -> Array: ...
    def forces(
        self, phi_rad: ArrayLike, tool: ModelTool, coef: Coefficients, cut: Cut, n_discs: int = 24
    ) -> Array: ...
    def mean_design(self, tool: ModelTool, cut: Cut) -> Array: ...
    def coefficient_vector(self, coef: Coefficients) -> Array: ...
    def coefficients(self, material: Material) -> Coefficients | None: ...
    def identifiable(self, fz_mm: Iterable[float]) -> tuple[str, ...]: ...
    def describes(self, tool: object) -> bool: ...


def _narrow(kind: type[_T], value: object, model: str, what: str) -> _T:
    """``value`` as the class this model works with, or one clear error."""
    if not isinstance(value, kind):
        raise AnalysisError(
            f"{what} of type {type(value).__name__}: the {model} model expects a {kind.__name__}"
        )
    return value


@dataclass(frozen=True)
class _Base:
    name: str
    label: str
    tool_schema: type[Model]
    coefficients_schema: type[Model]
    parameters: tuple[str, ...]
    edge_keys: tuple[str, ...]
    cutting_keys: tuple[str, ...]

    def identifiable(self, fz_mm: Iterable[float]) -> tuple[str, ...]:
        """The coefficients runs at these feeds per tooth (of one cutting geometry) can identify:
        the edge terms need three feeds at least. At one feed an edge force and a cutting force
        are one term; at two a size effect (force ~ h^m) fits as well as K h + P, so the
        identification's adequacy check (analysis.identify.adequacy) cannot decide."""
        feeds = {round(float(f), 9) for f in fz_mm}
        return self.cutting_keys + (self.edge_keys if len(feeds) >= EDGE_FEEDS else ())



@dataclass(frozen=True)
class FaceMillModel(_Base):
    """Seed 003's face mill with ploughing (:mod:`analysis.forces.facemill`)."""

    def describes(self, tool: object) -> TypeGuard[FaceMill]:
        """Whether this model describes ``tool`` (a tool of its class)."""
        return isinstance(tool, FaceMill)

    def coefficients(self, material: Material) -> FaceMillCoefficients | None:
        """The material's coefficients of this model, or None when it has none."""
        return material.facemill

    def teeth(self, tool: ModelTool) -> int:
        return _narrow(FaceMill, tool, self.name, "tool").inserts

    # The face mill's engagement does not depend on the tool (None allowed).
    def cut(self, tool: ModelTool | None, conditions: CutConditions) -> _fm.FaceMillCut:
        c = conditions
        if not math.isfinite(c.width_mm) or c.width_mm <= 0:
            raise AnalysisError(
                f"width_mm = {c.width_mm}: face-mill runs need the workpiece width (mm)"
            )
        return _fm.FaceMillCut(fz_mm=c.fz_mm, depth_mm=c.depth_mm, width_mm=c.width_mm,
                               center_offset_mm=c.center_offset_mm)  # fmt: skip

    def _args(self, tool: ModelTool, cut: Cut) -> tuple[FaceMill, _fm.FaceMillCut]:
        return (_narrow(FaceMill, tool, self.name, "tool"),
                _narrow(_fm.FaceMillCut, cut, self.name, "cut"))  # fmt: skip

    # n_discs: axial slices of models that slice the edge; the face mill's edge is tabulated.
    def design(self, phi_rad: ArrayLike, tool: ModelTool, cut: Cut,
               n_discs: int = 24) -> Array:  # fmt: skip
        return _fm.facemill_design(phi_rad, *self._args(tool, cut))

    def forces(self, phi_rad: ArrayLike, tool: ModelTool, coef: Coefficients,
               cut: Cut, n_discs: int = 24) -> Array:  # fmt: skip
        fm_tool, fm_cut = self._args(tool, cut)
        fm_coef = _narrow(FaceMillCoefficients, coef, self.name, "coefficients")
        return _fm.facemill_forces(phi_rad, fm_tool, fm_coef, fm_cut)

    def mean_design(self, tool: ModelTool, cut: Cut) -> Array:
        n = _FACEMILL_MEAN_ANGLES
        theta = 2 * np.pi * (np.arange(n) + 0.5) / n
        out: Array = _fm.facemill_design(theta, *self._args(tool, cut)).mean(axis=0)
        return out

    def coefficient_vector(self, coef: Coefficients) -> Array:
        fm_coef = _narrow(FaceMillCoefficients, coef, self.name, "coefficients")
        return _fm.coefficient_vector(fm_coef)


def _is_mode(mode: object) -> TypeGuard[Literal["up", "down", "slot"]]:
    return mode in ("up", "down", "slot")


@dataclass(frozen=True)
class EndMillModel(_Base):
    """The linear edge-force model of flat, ball and bull end mills
    (:mod:`analysis.forces.endmill`)."""

    def describes(self, tool: object) -> TypeGuard[EndMill]:
        """Whether this model describes ``tool`` (a tool of its class)."""
        return isinstance(tool, EndMill)

    def coefficients(self, material: Material) -> EndMillCoefficients | None:
        """The material's coefficients of this model, or None when it has none."""
        return material.endmill

    def teeth(self, tool: ModelTool) -> int:
        return _narrow(EndMill, tool, self.name, "tool").flutes

    def _args(self, tool: ModelTool, cut: Cut) -> tuple[EndMill, _em.EndMillCut]:
        return (_narrow(EndMill, tool, self.name, "tool"),
                _narrow(_em.EndMillCut, cut, self.name, "cut"))  # fmt: skip

    def cut(self, tool: ModelTool, conditions: CutConditions) -> _em.EndMillCut:
        c = conditions
        tool = _narrow(EndMill, tool, self.name, "tool")
        mode = c.mode if _is_mode(c.mode) else None
        if mode is None:
            raise AnalysisError(f"mode = {c.mode!r}: expected 'up', 'down' or 'slot'")
        ae = tool.diameter_mm if (mode == "slot" or not math.isfinite(c.width_mm)) else c.width_mm
        if mode != "slot" and not math.isfinite(c.width_mm):
            raise AnalysisError(
                f"width_mm missing: an end-mill {mode}-milling run needs the radial width of "
                "cut (mm)"
            )
        return _em.EndMillCut.from_width(tool, c.fz_mm, c.depth_mm, ae, mode,
                                         feed_angle_deg=c.feed_angle_deg)  # fmt: skip

    def design(self, phi_rad: ArrayLike, tool: ModelTool, cut: Cut,
               n_discs: int = 24) -> Array:  # fmt: skip
        return _em.endmill_design(phi_rad, *self._args(tool, cut), n_discs)

    def forces(self, phi_rad: ArrayLike, tool: ModelTool, coef: Coefficients,
               cut: Cut, n_discs: int = 24) -> Array:  # fmt: skip
        em_tool, em_cut = self._args(tool, cut)
        em_coef = _narrow(EndMillCoefficients, coef, self.name, "coefficients")
        return _em.endmill_forces(phi_rad, em_tool, em_coef, em_cut, n_discs)

    def mean_design(self, tool: ModelTool, cut: Cut) -> Array:
        return _em.mean_force_design(*self._args(tool, cut))

    def coefficient_vector(self, coef: Coefficients) -> Array:
        return _em.coefficient_vector(_narrow(EndMillCoefficients, coef, self.name, "coefficients"))


FACEMILL = FaceMillModel(
    name="facemill", label="face mill", tool_schema=FaceMill,
    coefficients_schema=FaceMillCoefficients, parameters=_fm.PARAMETERS,
    edge_keys=("P_T_n_mm", "P_R_n_mm", "P_A_n_mm"), cutting_keys=("K_T_n_mm2", "K_R", "K_A"),
)  # fmt: skip
ENDMILL = EndMillModel(
    name="endmill", label="end mill", tool_schema=EndMill,
    coefficients_schema=EndMillCoefficients, parameters=_em.PARAMETERS,
    edge_keys=("Kte_n_mm", "Kre_n_mm", "Kae_n_mm"),
    cutting_keys=("Ktc_n_mm2", "Krc_n_mm2", "Kac_n_mm2"),
)  # fmt: skip

#: Every model by its name (``--model``, the material's table).
MODELS: dict[str, ForceModel] = {m.name: m for m in (FACEMILL, ENDMILL)}


def model_for(tool: object) -> ForceModel:
    """The force model of a catalogue tool (the only test of a tool's class in cutlab)."""
    for model in MODELS.values():
        if model.describes(tool):
            return model
    raise AnalysisError(
        f"tool of kind {getattr(tool, 'kind', type(tool).__name__)!r}: no force model describes "
        f"it (models: {', '.join(MODELS)})"
    )


def model_named(name: str) -> ForceModel:
    """The model called ``name`` (``--model``)."""
    if name not in MODELS:
        raise AnalysisError(f"model {name!r}: expected one of {', '.join(MODELS)}")
    return MODELS[name]
