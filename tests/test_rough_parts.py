"""Part files for the roughing tests (helpers only: this module holds no tests)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planning.rough import Part, load_part


def _arr(a) -> str:
    return "[" + ", ".join(repr(float(v)) for v in np.ravel(a)) + "]"


def part_toml(
    x,
    y,
    z,
    *,
    top: float,
    stock_xy: tuple[float, float, float, float] | None = None,
    tool: str = "phi20-flat",
    tool_extra: str = "",
    cutting_extra: str = "",
    **rough,
) -> str:
    """TOML text of a height-field part; ``rough`` overrides [rough] keys."""
    x0, x1, y0, y1 = stock_xy or (float(x[0]), float(x[-1]), float(y[0]), float(y[-1]))
    settings = {
        "finish_allowance_mm": 1.0,
        "cusp_mm": 5.0,
        "dh_mm": 0.5,
        "optimal_dh_mm": 1.0,
        **rough,
    }
    lines = [
        'name = "test-part"',
        "[surface]",
        'kind = "height_field"',
        f"x_mm = {_arr(x)}",
        f"y_mm = {_arr(y)}",
        "z_mm = [",
        *(f"  {_arr(row)}," for row in np.asarray(z)),
        "]",
        "[stock]",
        f"x_min_mm = {x0}\nx_max_mm = {x1}\ny_min_mm = {y0}\ny_max_mm = {y1}",
        f"z_min_mm = 0.0\nz_max_mm = {top}",
        "[tool]",
        f'name = "{tool}"',
        tool_extra,
        "[cutting]",
        "feed_mm_min = 300.0\nspindle_rpm = 1000.0\nplunge_feed_mm_min = 100.0",
        cutting_extra,
        "[rough]",
        *(
            f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"'
            for k, v in settings.items()
        ),
    ]
    return "\n".join(lines) + "\n"


def write_toml(tmp_path: Path, text: str, name: str = "part.toml") -> Path:
    p = Path(tmp_path) / name
    p.write_text(text)
    return p


def load_toml(tmp_path: Path, text: str, name: str = "part.toml") -> Part:
    return load_part(write_toml(tmp_path, text, name))


def bump_grid(cx: float, cy: float, wx: float, wy: float, height: float, n: int = 11):
    """A smooth bump on an 80 x 80 mm field: heights z (n, n) over x = y = linspace(0, 80)."""
    x = np.linspace(0.0, 80.0, n)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    z = 10.0 + height * np.exp(-(((gx - cx) / wx) ** 2) - ((gy - cy) / wy) ** 2)
    return x, x, z
