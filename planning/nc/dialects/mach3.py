"""Mach3 (ArtSoft, "Using Mach3Mill" release 1.84), a PC control whose G-code language is NIST's
RS274NGC (the interpreter LinuxCNC's comes from), read from files: no DNC streaming.

Interpretation, as its manual describes it:

* order of execution as RS274NGC's: F is set before G20/G21, so an F in a block that switches
  units is in the old units; a G4 and a move may share a block (the dwell, then the move);
* G4 / G82 P in milliseconds: the General Config box "G04 Dwell param in Milliseconds" (taken
  as checked: "G4 5000" is 5 s; unchecked, P is seconds); no G4 X;
* G10 L1 (tool table) and L2 (work offsets, P1..P6 = G54..G59, absolute values); no L20;
* G28/G30 with no axis word return all axes; G90.1/G91.1 (the "IJ mode"); G61/G64;
* refused (unknown codes there): G29, G28.1/G30.1 (Mach3's G28.1 homes the axes to their
  switches, it stores no point), G38.2..G38.5 (Mach3 probes with G31), G43.1, G61.1,
  G92.2/G92.3 (none), G59.1..G59.3 (Mach3 selects more fixtures with G59 P7..), G97, G8; the
  M codes M50-M53, M60, M61, M62-M65 (M48/M49, enable/disable the overrides, exist);
* the machine's arc radius tolerance on the end radius; canned cycles positioned as the
  generic drill cycles.

Line answers: 256 characters a line; N0..N99999; an O word labels a subroutine (M98 P): a
program number there is a warning; ``;`` is not a documented comment (the manual lists ``( )``,
``//`` and ``%`` lines): a warning; the codes above.

Output: no ``%`` lines, no O word, N words as written, ``( )`` comments, decimals as the
program writes them, G4 P in milliseconds, tool changes ``T M6`` kept (Mach3 stops for the
change, or runs its M6 macros), canned cycles kept when the source reads them alike, G29
expanded, M30 appended when the program has no end; 256 characters a line.
"""

from __future__ import annotations

from planning.nc._codes import COMMON_G, COMMON_M
from planning.nc.dialects.base import Answer, Dialect, LineRules, PostRules

LINE_CHARS = 256  # "Using Mach3Mill" 10.5: a line holds up to 256 characters


def _refused(why: str) -> Answer:
    return Answer("error", f"unknown G-code ({why})")


_REFUSED_G = {
    "G29": _refused("Fanuc's return from the reference point; Mach3 has none"),
    "G28.1": _refused("Mach3's G28.1 homes the axes to their switches; it stores no point"),
    "G30.1": _refused("GRBL's and LinuxCNC's; Mach3 has none"),
    "G38.2": _refused("Mach3 probes with G31"),
    "G38.3": _refused("Mach3 probes with G31"),
    "G38.4": _refused("Mach3 probes with G31"),
    "G38.5": _refused("Mach3 probes with G31"),
    "G43.1": _refused("no dynamic tool length offset; G43 H"),
    "G61.1": _refused("LinuxCNC's exact stop; Mach3 has G61"),
    "G92.2": _refused("LinuxCNC's G92 suspend"),
    "G92.3": _refused("LinuxCNC's G92 restore"),
    "G59.1": _refused("LinuxCNC's extra work offset (Mach3: G59 P7..)"),
    "G59.2": _refused("LinuxCNC's extra work offset (Mach3: G59 P7..)"),
    "G59.3": _refused("LinuxCNC's extra work offset (Mach3: G59 P7..)"),
    "G97": _refused("no spindle speed modes in Mach3Mill"),
    "G8": _refused("LinuxCNC lathe radius mode"),
}
_REFUSED_M = {
    m: Answer("error", f"M{m} is a LinuxCNC M-code, not a Mach3 one")
    for m in (50, 51, 52, 53, 60, 61, 62, 63, 64, 65)
}

DIALECT = Dialect(
    name="mach3",
    title="Mach3",
    protocol=None,  # Mach3 runs files from the PC: no DNC streaming
    g_codes=COMMON_G,
    m_codes=COMMON_M | {48, 49},
    feed_before_units=True,
    dwell_p_ms=True,
    dwell_x=False,
    dwell_then_move=True,
    g10_l=(1, 2),
    g10_p_range=(1, 6),
    max_line_chars=LINE_CHARS,
    lines=LineRules(
        max_line_chars=LINE_CHARS,
        semicolon=Answer(
            "may not read it",
            "';' is not a Mach3 comment (the manual documents ( ), // and % lines)",
            "warning",
        ),
        refused_g=_REFUSED_G,
        refused_m=_REFUSED_M,
        o_word=Answer(
            "reads a subroutine label",
            "an O word labels a subroutine (M98 P) on Mach3, not a program number",
            "warning",
        ),
        sequence_number_max=99999,
        dwell_x=Answer("error", "Mach3's G4 takes P (milliseconds), not X"),
    ),
    post=PostRules(paren_comments=True, appends_m30=True),
)
