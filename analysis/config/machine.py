"""Machine configs (``configs/machines/*.toml``): travel, axes, spindle, feeds, the serial link
and the controller's dialect."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import AfterValidator, Field, model_validator

from analysis.config._base import mm_field as _mm
from analysis.validation import Model

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


__all__ = [
    "AxisTravel",
    "RotaryAxis",
    "FiveAxis",
    "SerialConfig",
    "DIALECT_NAMES",
    "REALTIME_OVERRIDE_DIALECTS",
    "MachineConfig",
]
