"""Validated TOML configs shared by every cutlab package.

Machines, tools, materials, dynamometers and DAQs are described in TOML files under ``configs/``.
They live here, in the lowest package, because all three packages read them. Every model is a
frozen pydantic model with ``extra="forbid"`` (:mod:`analysis.validation`): an unknown key is an
error, and every error names the file, the line, the dotted field, the value given and the expected
unit or range.

Units follow DESIGN.md: mm, mm/min, rpm, N, N/mm, N/mm^2, s, Hz and degrees in configs.

Where the configs are: ``$CUTLAB_CONFIG_DIR`` if set, else the ``configs/`` folder of the checkout
(cutlab is installed editable from its repository, see README).
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, Field, model_validator

from analysis.errors import ConfigError
from analysis.validation import Model, load_model

REPO_ROOT = Path(__file__).resolve().parents[2]


def config_dir() -> Path:
    """The folder holding cutlab's config files."""
    return Path(os.environ.get("CUTLAB_CONFIG_DIR", REPO_ROOT / "configs"))


def _mm(desc: str = "mm", **kw: Any) -> Any:
    return Field(description=desc, **kw)


# ----------------------------------------------------------------------------------------------
# Machine
# ----------------------------------------------------------------------------------------------


class AxisTravel(Model):
    """Travel of one linear axis in machine coordinates, mm."""

    min_mm: float = _mm()
    max_mm: float = _mm()

    @model_validator(mode="after")
    def _ordered(self) -> AxisTravel:
        if not self.max_mm > self.min_mm:
            raise ValueError(f"max_mm ({self.max_mm}) must be greater than min_mm ({self.min_mm})")
        return self


class RotaryAxis(Model):
    """A rotary axis of a 5-axis machine, degrees."""

    min_deg: float = Field(-360.0, description="deg")
    max_deg: float = Field(360.0, description="deg")
    rapid_deg_min: float = Field(5400.0, gt=0, le=1e6, description="deg/min, G0 rate")

    @model_validator(mode="after")
    def _ordered(self) -> RotaryAxis:
        if not self.max_deg > self.min_deg:
            raise ValueError(
                f"max_deg ({self.max_deg}) must be greater than min_deg ({self.min_deg})"
            )
        return self


class FiveAxis(Model):
    """Kinematics of a 5-axis machine for inverse kinematics (seed 002 output)."""

    kind: Literal[
        "table-table-AC", "head-table-AC", "table-table-BC", "head-head-AC", "head-head-BC"
    ] = Field(description="kinematic chain")
    a: RotaryAxis = RotaryAxis(min_deg=-120.0, max_deg=30.0)
    b: RotaryAxis = RotaryAxis(min_deg=-120.0, max_deg=120.0)
    c: RotaryAxis = RotaryAxis(min_deg=-360.0, max_deg=360.0)
    pivot_mm: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="mm, rotary-table centre (table kinematics) in machine axes"
    )
    head_pivot_length_mm: float = Field(0.0, ge=0, description="mm, spindle nose to head pivot")


class SerialConfig(Model):
    """RS-232 settings of the DNC link (pyserial names)."""

    port: str = Field("/dev/ttyUSB0", min_length=1, description="port name or pyserial URL")
    baudrate: int = Field(9600, gt=0, le=4_000_000, description="baud")
    bytesize: Literal[7, 8] = Field(7, description="data bits")
    parity: Literal["N", "E", "O"] = Field("E", description="N, E or O")
    stopbits: Literal[1, 2] = Field(2, description="stop bits")
    flow_control: Literal["xonxoff", "rtscts", "none"] = Field(
        "xonxoff", description="flow control"
    )
    xonxoff_in_streamer: bool = Field(
        True, description="handle DC1/DC3 in the streamer (USB adapters often ignore the kernel's)"
    )
    end_of_block: Literal["LF", "CRLF", "CR"] = Field("LF", description="end of block characters")
    code: Literal["ISO", "EIA"] = Field("ISO", description="tape code")
    leader_nuls: int = Field(0, ge=0, le=1000, description="count of NUL leader/trailer bytes")
    timeout_s: float = Field(10.0, gt=0, le=3600, description="s, no answer -> fault")
    program_folder: str = Field("", description="folder of programs served on remote request")


#: The dialects a machine file may name (the names of planning.nc.dialects.REGISTRY, whose modules
#: hold each control's rules), and those streamed with real-time override bytes (rig.dnc.protocols'
#: realtime_bytes). Data here as analysis cannot import planning or rig; tests check they agree.
DIALECT_NAMES = ("fanuc", "grbl", "linuxcnc", "mach3")
REALTIME_OVERRIDE_DIALECTS = ("grbl",)


def _known_dialect(name: str) -> str:
    if name not in DIALECT_NAMES:
        raise ValueError(f"dialect = {name!r}: expected one of {', '.join(DIALECT_NAMES)}")
    return name


class MachineConfig(Model):
    """A machining centre (or a lab mill) as cutlab needs to know it."""

    name: str = Field(min_length=1)
    description: str = ""
    dialect: Annotated[str, AfterValidator(_known_dialect)] = Field(
        "fanuc", description=f"controller dialect: {', '.join(DIALECT_NAMES)}"
    )
    tool_changer: bool = Field(
        True, description="M6 changes tools (false: a manual change, as on most GRBL mills)"
    )
    x: AxisTravel
    y: AxisTravel
    z: AxisTravel
    rapid_mm_min: float = Field(gt=0, le=200_000, description="mm/min")
    feed_min_mm_min: float = Field(gt=0, description="mm/min")
    feed_max_mm_min: float = Field(gt=0, le=200_000, description="mm/min")
    spindle_max_rpm: float = Field(gt=0, le=100_000, description="rpm")
    spindle_min_rpm: float = Field(0.0, ge=0, description="rpm")
    # The spindle's rated curve (planning.limits): constant torque up to the base speed
    # P / T, constant power above it. Unset: no power or torque limit.
    spindle_power_kw: float | None = Field(
        None, gt=0, le=1000, description="kW, rated spindle power (constant-power region)"
    )
    spindle_torque_nm: float | None = Field(
        None, gt=0, le=50_000, description="N m, rated spindle torque (constant-torque region)"
    )
    arc_radius_tolerance_mm: float = Field(
        0.002, gt=0, le=1, description="mm, arc end radius mismatch"
    )
    min_arc_radius_mm: float = Field(0.0, ge=0, description="mm, smallest arc the control can cut")
    accel_mm_s2: float | None = Field(
        None, gt=0, le=100_000, description="mm/s^2, path acceleration (unset: times ignore it)"
    )
    junction_deviation_mm: float = Field(
        0.01, gt=0, le=10, description="mm, corner speed model of the look-ahead planner"
    )
    reference_mm: tuple[float, float, float] | None = Field(
        None, description="mm, machine X Y Z of the G28 reference point (default: travel max)"
    )
    second_reference_mm: tuple[float, float, float] | None = Field(
        None, description="mm, machine X Y Z of the G30 second reference point (default: G28's)"
    )
    serial: SerialConfig = SerialConfig()
    five_axis: FiveAxis | None = None
    # How an override reaches the control from outside (rig.adaptive): GRBL 1.1's real-time bytes,
    # a wired input (PMC / analog override from a DAQ output), or none; unset: by dialect.
    override: Literal["grbl-realtime", "none", "external-analog"] | None = Field(
        None,
        description="how an override reaches the control (unset: by dialect, GRBL's bytes or none)",
    )

    @property
    def override_path(self) -> str:
        if self.override is not None:
            return self.override
        return "grbl-realtime" if self.dialect in REALTIME_OVERRIDE_DIALECTS else "none"

    @model_validator(mode="after")
    def _feeds(self) -> MachineConfig:
        if self.override == "grbl-realtime" and self.dialect not in REALTIME_OVERRIDE_DIALECTS:
            raise ValueError(
                f'override = "grbl-realtime": only GRBL 1.1 takes real-time override bytes '
                f'(dialect = "{self.dialect}"); expected "none" or "external-analog"'
            )
        if not self.feed_max_mm_min > self.feed_min_mm_min:
            raise ValueError(
                f"feed_max_mm_min ({self.feed_max_mm_min}) must exceed feed_min_mm_min "
                f"({self.feed_min_mm_min})"
            )
        for name in ("reference_mm", "second_reference_mm"):
            point = getattr(self, name)
            for axis, value in zip("xyz", point or ()):
                travel = getattr(self, axis)
                if not travel.min_mm <= value <= travel.max_mm:
                    raise ValueError(
                        f"{name} {axis.upper()} = {value} mm is outside the {axis} travel "
                        f"{travel.min_mm}..{travel.max_mm} mm"
                    )
        return self

    @property
    def reference_point_mm(self) -> tuple[float, float, float]:
        """Machine X Y Z the axes return to on G28, mm (``reference_mm`` or the travel maxima,
        where most machining centres home)."""
        if self.reference_mm is not None:
            return self.reference_mm
        return (self.x.max_mm, self.y.max_mm, self.z.max_mm)

    @property
    def second_reference_point_mm(self) -> tuple[float, float, float]:
        """Machine X Y Z the axes return to on G30 (P2), mm (default: the G28 point)."""
        return self.second_reference_mm or self.reference_point_mm


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


# ----------------------------------------------------------------------------------------------
# Dynamometer, amplifier and DAQ
# ----------------------------------------------------------------------------------------------


class FormerModeNames:
    """The former attribute names of a mode (``frequency_hz``, ``damping_ratio``), for code not
    yet moved to the one mode schema (``f_hz``, ``zeta``)."""

    f_hz: float
    zeta: float

    @property
    def frequency_hz(self) -> float:
        return self.f_hz

    @property
    def damping_ratio(self) -> float:
        return self.zeta


class Mode(Model, FormerModeNames):
    """One structural mode of the dynamometer (seed 003 Table 2), in the one mode schema."""

    axis: Literal["x", "y", "z"]
    f_hz: float = Field(gt=0, le=200_000, description="Hz, natural frequency")
    zeta: float = Field(gt=0, lt=1, description="damping ratio, fraction of critical")

    @model_validator(mode="before")
    @classmethod
    def _renamed(cls, data: Any) -> Any:
        return renamed_mode_fields(data)



class DynoChannel(Model):
    """One force channel: dynamometer sensitivity and the charge amplifier's range."""

    name: str = Field(min_length=1)
    axis: Literal["x", "y", "z"]
    sign: Literal[1, -1] = Field(1, description="+1 or -1, dynamometer axis to cutlab axis")
    sensitivity_pc_n: float = Field(description="pC/N (Kistler 9257B: about -7.5 x/y, -3.7 z)")
    range_n_v: float = Field(gt=0, le=1e6, description="N/V, amplifier scale (range / 10 V)")

    @model_validator(mode="before")
    @classmethod
    def _signed_axis(cls, data: Any) -> Any:
        # axis = "-y": the channel is cutlab's y with its sign flipped (same as sign = -1).
        if isinstance(data, dict) and isinstance(data.get("axis"), str):
            axis = data["axis"].strip()
            if axis[:1] in "+-" and axis[1:].strip():
                flip = -1 if axis[0] == "-" else 1
                data = {**data, "axis": axis[1:].strip(), "sign": flip * data.get("sign", 1)}
        return data

    @model_validator(mode="after")
    def _nonzero(self) -> DynoChannel:
        if self.sensitivity_pc_n == 0:
            raise ValueError("sensitivity_pc_n = 0: a sensitivity must be non-zero (pC/N)")
        return self


class Dynamometer(Model):
    model: str = Field(min_length=1)
    description: str = ""
    channels: tuple[DynoChannel, ...] = Field(min_length=1)
    crosstalk: tuple[tuple[float, ...], ...] | None = Field(
        None, description="square matrix, measured = C @ true, from the calibration sheet"
    )
    modes: tuple[Mode, ...] = ()
    modes_without_workpiece: tuple[Mode, ...] = ()
    calibration_id: str = Field("", description="identity of the calibration sheet")
    axes: str | None = Field(
        None,
        pattern=r"^\s*[xyzXYZ]\s*=\s*[+-]?[^,=]+(,\s*[xyzXYZ]\s*=\s*[+-]?[^,=]+){2}$",
        description="export columns for cutlab's x, y, z, e.g. 'x=-Fy,y=Fx,z=Fz' (imports)",
    )

    @model_validator(mode="after")
    def _shape(self) -> Dynamometer:
        n = len(self.channels)
        if self.crosstalk is not None:
            rows = len(self.crosstalk)
            cols = {len(r) for r in self.crosstalk}
            if rows != n or cols != {n}:
                raise ValueError(
                    f"crosstalk is {rows} x {sorted(cols)}: expected {n} x {n} for {n} channels"
                )
        names = [c.name for c in self.channels]
        if len(set(names)) != n:
            raise ValueError(f"channel names repeat: {names}")
        return self


class DaqConfig(Model):
    """An NI DAQ task (or the simulated DAQ's matching settings)."""

    device: str = Field("Dev1", min_length=1, description="NI device name")
    channels: tuple[str, ...] = Field(
        ("Dev1/ai0", "Dev1/ai1", "Dev1/ai2"), min_length=1, description="physical channels"
    )
    rate_hz: float = Field(10_000.0, gt=0, le=10_000_000, description="Hz, per channel")
    input_range_v: float = Field(10.0, gt=0, le=100, description="V, symmetric +-range")
    terminal_config: Literal["DIFF", "RSE", "NRSE", "PSEUDO_DIFF", "DEFAULT"] = "DIFF"
    buffer_s: float = Field(5.0, gt=0, le=600, description="s of samples held by the driver")
    read_interval_s: float = Field(0.1, gt=0, le=10, description="s between reads")
    raw: bool = Field(True, description="read int16 ADC codes and store the scaling")


class RigConfig(Model):
    """Dynamometer + DAQ of one rig, as a file ``configs/rig.toml``."""

    dynamometer: Dynamometer
    daq: DaqConfig = DaqConfig()


def _resolve(name_or_path: str | Path, sub: str) -> Path:
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        return p
    cand = config_dir() / sub / f"{name_or_path}.toml"
    if cand.exists():
        return cand
    known = sorted(q.stem for q in (config_dir() / sub).glob("*.toml"))
    raise ConfigError(f"{sub[:-1]} '{name_or_path}' not found: not a file, and not one of {known}")


def load_machine(name_or_path: str | Path = "ace-h63") -> MachineConfig:
    """A machine by file path or by name in ``configs/machines/``."""
    return load_model(MachineConfig, _resolve(name_or_path, "machines"))


# User catalogues (issue 17): files next to the user's data, consulted before the shipped
# configs/tools.toml and configs/materials.toml, so that nobody edits the install. A module-level
# list, not a context variable: campaign runners read tools from worker threads.
_USER_CATALOGS: dict[str, list[str]] = {"tools": [], "materials": []}


@contextmanager
def user_catalogs(
    tools: str | Path | None = None, materials: str | Path | None = None
) -> Iterator[None]:
    """Within the block, :func:`get_tool` / :func:`load_tools` (and the material ones) look in
    ``tools`` / ``materials`` first: a name there shadows the shipped one. Each file is read now,
    so a bad one is one error naming it, before any work."""
    added = []
    for kind, path in (("tools", tools), ("materials", materials)):
        if path is None:
            continue
        if "\0" in str(path):  # open() would raise ValueError, not a config error
            raise ConfigError(f"{str(path)!r}: not a file name (it holds a NUL character)")
        (_tool_library if kind == "tools" else _material_library)(str(path))
        _USER_CATALOGS[kind].insert(0, str(path))
        added.append(kind)
    try:
        yield
    finally:
        for kind in added:
            _USER_CATALOGS[kind].pop(0)


def _catalog_files(kind: str, path: str | Path | None) -> list[str]:
    """The files searched, first match wins: ``path`` alone, else the user ones then shipped."""
    if path is not None:
        return [str(path)]
    return [*_USER_CATALOGS[kind], str(config_dir() / f"{kind}.toml")]


def catalog_source(kind: str, name: str) -> str:
    """The file a :func:`get_tool` (``kind`` "tools") or :func:`get_material` ("materials") of
    ``name`` reads it from now: the first of the user catalogues and the shipped file that holds
    it ("" if none does), so that a message about the tool names the user's file."""
    read = _tool_library if kind == "tools" else _material_library
    for f in _catalog_files(kind, None):
        if name in getattr(read(f), kind):
            return f
    return ""


def _not_found(kind: str, name: str, path: str | Path | None, known: list[str]) -> ConfigError:
    first, *rest = _catalog_files(f"{kind}s", path)
    nor = f" (nor in {', '.join(rest)})" if rest else ""
    return ConfigError(
        f"{first}: {kind} '{name}' not found{nor}; known {kind}s: {', '.join(sorted(known))}"
    )


@lru_cache(maxsize=8)
def _tool_library(path: str) -> ToolLibrary:
    return load_model(ToolLibrary, path)


def load_tools(path: str | Path | None = None) -> dict[str, EndMill | FaceMill]:
    """All tools of a tool library file (default: the user catalogues, then
    ``configs/tools.toml``; a user name shadows the shipped one)."""
    out: dict[str, EndMill | FaceMill] = {}
    for f in reversed(_catalog_files("tools", path)):
        out.update(_tool_library(f).tools)
    return out


def get_tool(name: str, path: str | Path | None = None) -> EndMill | FaceMill:
    tools = load_tools(path)
    if name not in tools:
        raise _not_found("tool", name, path, list(tools))
    return tools[name]


@lru_cache(maxsize=8)
def _material_library(path: str) -> MaterialLibrary:
    return load_model(MaterialLibrary, path)


def load_materials(path: str | Path | None = None) -> dict[str, Material]:
    """All materials (default: the user catalogues, then ``configs/materials.toml``)."""
    out: dict[str, Material] = {}
    for f in reversed(_catalog_files("materials", path)):
        out.update(_material_library(f).materials)
    return out


def get_material(name: str, path: str | Path | None = None) -> Material:
    mats = load_materials(path)
    if name not in mats:
        raise _not_found("material", name, path, list(mats))
    return mats[name]


def load_rig(path: str | Path | None = None) -> RigConfig:
    """Dynamometer and DAQ settings (default ``configs/rig.toml``)."""
    return load_model(RigConfig, path or config_dir() / "rig.toml")
