"""The tool catalogue (``configs/tools.toml``: end mills and face mills, their holders and modes)
and the material catalogue (``configs/materials.toml``: force coefficients)."""

from __future__ import annotations

import math
import warnings
from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from analysis.validation import Model

# ----------------------------------------------------------------------------------------------
# Tools
# ----------------------------------------------------------------------------------------------


class Holder(Model):
    """Tool holder and spindle nose as stacked cylinders above the cutter (5-axis, Z-map checks)."""

    diameter_mm: float = Field(40.0, gt=0, le=500, description="mm")
    length_mm: float = Field(60.0, gt=0, le=1000, description="mm")
    spindle_nose_diameter_mm: float = Field(100.0, gt=0, le=1000, description="mm")
    spindle_nose_length_mm: float = Field(100.0, gt=0, le=2000, description="mm")


#: One mode schema everywhere (the catalogue's): ``axis``, ``f_hz``, ``zeta``, ``k_N_m``, ``m_kg``
#: in the tool catalogue, the dynamometer's modes, modes files and stability cases. The former
#: names are still read, with a deprecation note, so that users' files keep loading.
MODE_FIELD_RENAMES = {
    "direction": "axis", "frequency_hz": "f_hz", "damping_ratio": "zeta",
    "stiffness_n_m": "k_N_m", "mass_kg": "m_kg",
}  # fmt: skip


def renamed_mode_fields(data: object) -> object:
    """A mode's table with its former field names replaced (a deprecation note says which)."""
    if not isinstance(data, dict):
        return data
    old = [k for k in data if k in MODE_FIELD_RENAMES]
    if not old:
        return data
    out = dict(data)
    for k in old:
        new = MODE_FIELD_RENAMES[k]
        if new in out:
            raise ValueError(f"{k} and {new} both given: {k} is the former name of {new}")
        out[new] = out.pop(k)
    pairs = ", ".join(f"{k} -> {MODE_FIELD_RENAMES[k]}" for k in old)
    warnings.warn(f"deprecated mode field name(s) {pairs}: one mode schema (axis, f_hz, zeta, "
                  "k_N_m, m_kg); the former names are read for now", FutureWarning,
                  stacklevel=2)  # fmt: skip
    return out


class Provenance(Model):
    """Where a measured figure came from: ``source`` (what was measured, on what), ``date``
    (ISO), ``command`` (how to measure it again) and the ``file`` it was measured from."""

    source: str = Field(min_length=1)
    date: str = Field(pattern=r"^\d{4}-\d{2}-\d{2}$", description="YYYY-MM-DD")
    command: str = ""
    file: str = ""


class ToolMode(Model):
    """One bending mode of the tool (with holder and spindle) at its tip, in one machine direction:
    what an impact test on the tool gives (``cutlab analyze modal --save``), with its
    ``provenance``. ``plan check`` computes the stability limit from them."""

    axis: Literal["x", "y"]
    f_hz: float = Field(gt=0, le=50_000, description="Hz, natural frequency")
    zeta: float = Field(gt=0, lt=1, description="damping ratio (typically 0.01..0.1)")
    k_N_m: float = Field(gt=0, le=1e10, description="N/m, modal stiffness at the tip")
    provenance: Provenance | None = None

    @model_validator(mode="before")
    @classmethod
    def _renamed(cls, data: Any) -> Any:
        return renamed_mode_fields(data)


class EndMill(Model):
    """A flat, ball or bull-nose end mill. Ball: corner radius = D/2; flat: 0; bull: in between.

    ``max_chip_mm`` is the upper end of the edge's chip-thickness range (the catalogue's largest
    h_ex); above it the chip jams in the chip breaker and the cutting pressures rise by
    ``overload_gain`` per unit relative excess (rig.sim._regen). ``modes``: see :class:`ToolMode`.
    """

    kind: Literal["flat", "ball", "bull"]
    description: str = ""
    diameter_mm: float = Field(gt=0, le=200, description="mm")
    corner_radius_mm: float = Field(0.0, ge=0, description="mm")
    flute_length_mm: float = Field(gt=0, le=500, description="mm")
    flutes: int = Field(ge=1, le=16, description="count")
    helix_deg: float = Field(30.0, ge=0, lt=80, description="deg")
    stickout_mm: float | None = Field(None, gt=0, le=1000, description="mm, gauge length")
    shank_diameter_mm: float | None = Field(None, gt=0, le=200, description="mm")
    runout_mm: float = Field(0.0, ge=0, le=1, description="mm, radial runout of the cutter")
    material: str = Field("carbide", description="cutter material")
    holder: Holder = Holder()
    modes: tuple[ToolMode, ...] = Field((), description="tool-tip modes (x, y)")
    max_chip_mm: float | None = Field(
        None, gt=0, le=2, description="mm, largest chip thickness h_ex the edge takes cleanly"
    )
    overload_gain: float = Field(
        3.0, ge=0, le=100, description="cutting-pressure rise per unit relative excess of h_ex"
    )
    # Static deflection limit (planning.limits): cantilever of the stick-out, unset: no limit.
    deflection_tol_mm: float | None = Field(
        None, gt=0, le=5, description="mm, largest static tool-tip deflection allowed"
    )
    youngs_modulus_gpa: float | None = Field(
        None, gt=0, le=1500, description="GPa, cutter's E (default by material: HSS, carbide)"
    )
    # The adaptive loop's hard cap (rig.adaptive): a resultant above it holds the feed.
    max_force_n: float | None = Field(None, gt=0, le=1e6, description="N, resultant -> feed hold")

    @model_validator(mode="after")
    def _geometry(self) -> EndMill:
        r = self.diameter_mm / 2
        rc = self.corner_radius_mm
        if self.kind == "flat" and rc != 0:
            raise ValueError(f"corner_radius_mm = {rc}: a flat end mill has corner radius 0 mm")
        if self.kind == "ball" and not math.isclose(rc, r, rel_tol=1e-9):
            raise ValueError(
                f"corner_radius_mm = {rc}: a ball end mill has corner radius D/2 = {r} mm"
            )
        if self.kind == "bull" and not 0 < rc < r:
            raise ValueError(
                f"corner_radius_mm = {rc}: a bull end mill needs 0 < corner radius < D/2 = {r} mm"
            )
        if self.stickout_mm is not None and self.stickout_mm < self.flute_length_mm:
            raise ValueError(
                f"stickout_mm = {self.stickout_mm} is shorter than flute_length_mm = "
                f"{self.flute_length_mm}"
            )
        return self

    @property
    def radius_mm(self) -> float:
        return self.diameter_mm / 2

    @property
    def length_mm(self) -> float:
        """Cutter length below the holder, mm (stickout, or 1.5 x flute length if not given)."""
        return self.stickout_mm if self.stickout_mm is not None else 1.5 * self.flute_length_mm


class FaceMill(Model):
    """An indexable face mill (seed 003: M415SP04R-12 with SPGN120304 inserts)."""

    kind: Literal["facemill"]
    description: str = ""
    diameter_mm: float = Field(gt=0, le=1000, description="mm")
    inserts: int = Field(ge=1, le=64, description="count")
    lead_angle_deg: float = Field(ge=-10, le=80, description="deg, gamma_L")
    axial_rake_deg: float = Field(ge=-30, le=30, description="deg, gamma_A")
    radial_rake_deg: float = Field(ge=-30, le=30, description="deg, gamma_R")
    nose_radius_mm: float = Field(ge=0, le=10, description="mm")
    insert_edge_length_mm: float = Field(12.7, gt=0, le=50, description="mm, usable cutting edge")
    max_depth_mm: float | None = Field(None, gt=0, le=50, description="mm, largest axial depth")
    insert_angles_deg: tuple[float, ...] | None = Field(
        None, description="deg, angular positions of the inserts (default: evenly spaced)"
    )
    runout_mm: float = Field(0.0, ge=0, le=1, description="mm, radial runout per insert")
    holder: Holder = Holder(diameter_mm=60.0, length_mm=50.0)
    max_force_n: float | None = Field(None, gt=0, le=1e6, description="N, resultant -> feed hold")

    @model_validator(mode="after")
    def _geometry(self) -> FaceMill:
        if self.insert_angles_deg is not None and len(self.insert_angles_deg) != self.inserts:
            raise ValueError(
                f"insert_angles_deg has {len(self.insert_angles_deg)} entries, "
                f"inserts = {self.inserts}"
            )
        if self.nose_radius_mm >= self.insert_edge_length_mm:
            raise ValueError(
                f"nose_radius_mm = {self.nose_radius_mm} must be smaller than "
                f"insert_edge_length_mm = {self.insert_edge_length_mm}"
            )
        return self

    @property
    def radius_mm(self) -> float:
        return self.diameter_mm / 2

    @property
    def depth_limit_mm(self) -> float:
        """Deepest axial cut the inserts allow, mm."""
        if self.max_depth_mm is not None:
            return self.max_depth_mm
        return self.insert_edge_length_mm * math.cos(math.radians(self.lead_angle_deg))

    @property
    def flute_length_mm(self) -> float:
        return self.depth_limit_mm


Tool = Annotated[EndMill | FaceMill, Field(discriminator="kind")]


class ToolLibrary(Model):
    tools: dict[str, Tool]


# ----------------------------------------------------------------------------------------------
# Materials
# ----------------------------------------------------------------------------------------------


class FaceMillCoefficients(Model):
    """Seed 003 eqs 3-4: F_T' = P_T l + K_T S, F_R' = P_R l + K_R K_T S, with an axial pair."""

    K_T_n_mm2: float = Field(gt=0, le=20_000, description="N/mm^2, specific cutting pressure")
    K_R: float = Field(
        ge=0, le=10, description="ratio K_R' (seed 003 prints N/mm^2; eq 4 makes it a ratio)"
    )
    P_T_n_mm: float = Field(ge=0, le=5_000, description="N/mm, ploughing force per edge length")
    P_R_n_mm: float = Field(ge=0, le=5_000, description="N/mm, ploughing force per edge length")
    K_A: float = Field(0.0, ge=-10, le=10, description="ratio, axial cutting force to tangential")
    P_A_n_mm: float = Field(0.0, ge=-5_000, le=5_000, description="N/mm, axial ploughing force")


class EndMillCoefficients(Model):
    """Linear edge-force model: dF = K_c h db + K_e db per direction (Altintas)."""

    Ktc_n_mm2: float = Field(gt=0, le=20_000, description="N/mm^2")
    Krc_n_mm2: float = Field(ge=0, le=20_000, description="N/mm^2")
    Kac_n_mm2: float = Field(ge=-20_000, le=20_000, description="N/mm^2")
    Kte_n_mm: float = Field(ge=0, le=5_000, description="N/mm")
    Kre_n_mm: float = Field(ge=0, le=5_000, description="N/mm")
    Kae_n_mm: float = Field(ge=-5_000, le=5_000, description="N/mm")


class Material(Model):
    description: str = ""
    density_kg_m3: float = Field(gt=0, le=25_000, description="kg/m^3")
    hardness_hb: float | None = Field(None, gt=0, le=1000, description="HB")
    facemill: FaceMillCoefficients | None = None
    endmill: EndMillCoefficients | None = None


class MaterialLibrary(Model):
    materials: dict[str, Material]


__all__ = [
    "Holder",
    "MODE_FIELD_RENAMES",
    "renamed_mode_fields",
    "Provenance",
    "ToolMode",
    "EndMill",
    "FaceMill",
    "ToolLibrary",
    "FaceMillCoefficients",
    "EndMillCoefficients",
    "Material",
    "MaterialLibrary",
    "Tool",
]
