"""The rig (``configs/rig.toml``): the dynamometer, its amplifier channels and modes, the DAQ."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, model_validator

from analysis.config.tools import renamed_mode_fields
from analysis.validation import Model

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


__all__ = [
    "FormerModeNames",
    "Mode",
    "DynoChannel",
    "Dynamometer",
    "DaqConfig",
    "RigConfig",
]
