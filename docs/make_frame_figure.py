"""Draw docs/frame.png: cutlab's force frame for end milling (README, "I have DynoWare exports").

Top view: x the feed (the tool's motion through the workpiece), y = z x x, the spindle clockwise
seen from above (M3), a tooth sweeping from +y through +x to -y; down milling engages the -y
side, up milling the +y side; the mean forces ON THE WORKPIECE in a slot (x ahead, y with the
teeth). Side view: z along the tool axis, up from the workpiece towards the spindle, the mean
axial force on the workpiece up. Run: .venv/bin/python docs/make_frame_figure.py
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, FancyArrowPatch, Rectangle  # noqa: E402

OUT = Path(__file__).resolve().parent / "frame.png"


def _arrow(ax, xy0, xy1, color="k", lw=1.6, style="-|>", **kw):
    ax.add_patch(FancyArrowPatch(xy0, xy1, arrowstyle=style, mutation_scale=14, color=color,
                                 lw=lw, **kw))  # fmt: skip


def main() -> Path:
    fig, (top, side) = plt.subplots(1, 2, figsize=(9, 4.2), dpi=90)
    # Top view: the slot's walls, the tool, the axes.
    top.add_patch(Rectangle((-3.2, -1), 3.2, 2, color="0.85"))  # the slot already cut
    top.add_patch(Rectangle((-3.2, 1), 6.4, 1.4, color="0.7"))
    top.add_patch(Rectangle((-3.2, -2.4), 6.4, 1.4, color="0.7"))
    top.add_patch(Rectangle((0, -1), 3.2, 2, color="0.7"))
    top.add_patch(Circle((0, 0), 1, fc="white", ec="k", lw=1.2))
    th = np.linspace(np.radians(60), np.radians(-200), 60)  # clockwise from above
    top.plot(0.6 * np.cos(th), 0.6 * np.sin(th), "k", lw=1)
    _arrow(top, (0.6 * np.cos(th[-2]), 0.6 * np.sin(th[-2])),
           (0.6 * np.cos(th[-1]), 0.6 * np.sin(th[-1])))  # fmt: skip
    top.text(0, 0, "M3", ha="center", va="center", fontsize=8)
    _arrow(top, (-2.9, -3.0), (-1.6, -3.0), "C0")
    _arrow(top, (-2.9, -3.0), (-2.9, -1.7), "C0")
    top.text(-1.5, -3.0, "+x feed", color="C0", va="center", fontsize=9)
    top.text(-2.9, -1.55, "+y", color="C0", ha="center", fontsize=9)
    top.text(-3.35, -3.3, "z out of the page", color="C0", fontsize=8, va="top")
    _arrow(top, (1.0, 0), (2.1, 0), "C3", lw=2.2)
    top.text(2.15, 0.15, "mean Fx > 0", color="C3", fontsize=8)
    _arrow(top, (0, -1.0), (0, -1.9), "C3", lw=2.2)
    top.text(-0.15, -1.75, "mean Fy < 0", color="C3", fontsize=8, ha="right")
    top.text(0.9, 1.7, "up milling: +y side", fontsize=8, ha="left")
    top.text(1.1, -1.75, "down milling: -y side", fontsize=8, ha="left")
    top.text(0, 2.75, "top view: forces on the workpiece, slot", ha="center", fontsize=9)
    top.set_xlim(-3.6, 3.4)
    top.set_ylim(-3.6, 3.0)
    # Side view: the tool above the workpiece, z up.
    side.add_patch(Rectangle((-3, -2), 6, 1.6, color="0.7"))
    side.add_patch(Rectangle((-0.5, -0.9), 1.0, 3.2, fc="white", ec="k"))
    side.add_patch(Rectangle((-0.9, 2.3), 1.8, 0.6, color="0.5"))
    side.text(0, 3.05, "spindle", ha="center", fontsize=8)
    _arrow(side, (-2.6, 0.2), (-2.6, 1.5), "C0")
    _arrow(side, (-2.6, 0.2), (-1.3, 0.2), "C0")
    side.text(-2.6, 1.6, "+z tool axis", color="C0", ha="center", fontsize=9)
    side.text(-1.2, 0.2, "+x", color="C0", va="center", fontsize=9)
    _arrow(side, (1.4, -1.2), (1.4, -0.1), "C3", lw=2.2)
    side.text(1.55, -0.6, "mean Fz > 0\n(pulled up the helix)", color="C3", fontsize=8)
    side.text(0, -2.4, "workpiece (a table dynamometer measures its forces)", ha="center",
              fontsize=8)  # fmt: skip
    side.set_xlim(-3.2, 3.4)
    side.set_ylim(-2.8, 3.4)
    for ax in (top, side):
        ax.set_aspect("equal")
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(OUT)
    plt.close(fig)
    return OUT


if __name__ == "__main__":
    print(main())
