"""LinuxCNC 2.9 (rs274ngc), as its interpreter ``rs274`` runs a program to the canonical move
(tests/test_nc_rs274.py compares the two segment by segment).

Interpretation: F is read before G20/G21 (its order of execution: ``G21 ... G20 F6`` is 6 mm/min)
and G94 always clears it; G4 / G82 P in seconds, no G4 X, and a G4 block may move after the
dwell; G10 L0/L1/L2/L10/L11/L20 (P0..P9, G54..G59.3; absolute values); G28/G30 with no axis word
move all axes, the rotary axes too; G53 is refused under G91; a G38.x target within 0.254 mm is
an error; LinuxCNC's arc rule (the end radius within 0.0283 mm / 0.00283 in, or within 0.1 % up
to 100 times that: a spiral; its own tolerance unless the machine file sets one); G2/G3 P turns;
F along X Y Z with the rotary axes following; canned cycles as rs274ngc positions and pecks them
(0.010 in G83 re-entry). Its own codes: G28.1/G30.1, G43.1, G38.2..G38.5, G61.1, G92.2/G92.3,
G59.1..G59.3, G97, G8 and M48-M53, M60, M61, M62-M65.

Line answers: 255 characters a line; G29 is unknown; an O word is an o-word (a program number is
refused); G4 X is refused and a G4 P of 100 s or more is worth a warning.

Output: ``%`` on the first and last line, M30 appended when the program has no end, no O word,
G29 expanded, G80 left out of a block with another motion code, a G94 that would clear the feed
left out; 255 characters a line.
"""

from __future__ import annotations

from planning.nc._codes import COMMON_G, COMMON_M, INCH_MM
from planning.nc.dialects.base import Answer, Dialect, LineRules, PostRules

LINE_CHARS = 255  # LinuxCNC reads 255 characters a line

DIALECT = Dialect(
    name="linuxcnc",
    title="LinuxCNC",
    protocol=None,  # LinuxCNC reads files: no DNC streaming
    g_codes=COMMON_G | {281, 301, 611, 922, 923, 591, 592, 593, 970, 80, 431, 382, 383, 384, 385},
    m_codes=COMMON_M | {48, 49, 50, 51, 52, 53, 60, 61, 62, 63, 64, 65},
    feed_before_units=True,
    g94_clears_feed=True,
    dwell_x=False,
    dwell_then_move=True,
    home_rotary=True,
    g10_l=(0, 1, 2, 10, 11, 20),
    g10_p_range=(0, 9),
    g53_needs_absolute=True,
    probe_min_mm=0.254,  # 0.01 in
    arc_spiral=True,
    arc_turns_p=True,
    feed_along_xyz=True,
    cycles_rs274ngc=True,
    peck_clearance_mm=0.010 * INCH_MM,  # rs274ngc's G83_RAPID_DELTA, 0.010 in
    max_line_chars=LINE_CHARS,
    lines=LineRules(
        max_line_chars=LINE_CHARS,
        refused_g={
            "G29": Answer(
                "error",
                "unknown G-code (Fanuc's return from the reference point; LinuxCNC has none)",
            )
        },
        o_word=Answer(
            "error",
            "an O word is an o-word (subroutine or flow control) on LinuxCNC; a program number "
            "is refused",
        ),
        dwell_x=Answer("error", "LinuxCNC's G4 takes P (seconds), not X"),
        dwell_p_warn_s=100.0,
    ),
    post=PostRules(wraps_percent=True, appends_m30=True),
)
