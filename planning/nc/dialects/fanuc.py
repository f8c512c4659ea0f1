"""Fanuc (0i/30i series, ISO code): the default dialect, what the planners write.

Interpretation: G4 / G82 ``P`` in milliseconds (``G4 X`` in seconds); F after G20/G21 is in the
new units; G10 L2 (P1..P6 = G54..G59; under G91 the values add) and the tool offset memories L1,
L10..L13 (not modelled); G28/G30 need the axes to return; G29 returns from the reference point;
the machine's arc radius tolerance.

Line answers: ``;`` is the end of block (alarm), lower-case letters are not ISO tape code, the
codes of other controls are ``PS0010 improper G-code``, O1..O9999 and N1..N99999, length words
without a decimal point are least increments (0.001 mm) unless parameter 3401#0 (DPI) is set.

Output: ``%``, O and N as written, ISO words (upper case, a decimal point in every length and
angle word), ``( )`` comments, G4 X in seconds, no G90.1/G91.1 (centres written relative).
"""

from __future__ import annotations

from planning.nc._codes import COMMON_G, COMMON_M
from planning.nc.dialects.base import Answer, Dialect, LineRules, PostRules

_IMPROPER = "alarm PS0010"
_REFUSED_G = {
    "G28.1": "stores the reference point on GRBL/LinuxCNC only",
    "G30.1": "stores the reference point on GRBL/LinuxCNC only",
    "G61.1": "LinuxCNC's exact stop",
    "G92.2": "LinuxCNC's G92 suspend",
    "G92.3": "LinuxCNC's G92 restore",
    "G59.1": "LinuxCNC's extra work offset (Fanuc: G54.1 Pn)",
    "G59.2": "LinuxCNC's extra work offset (Fanuc: G54.1 Pn)",
    "G59.3": "LinuxCNC's extra work offset (Fanuc: G54.1 Pn)",
    "G90.1": "arc centres are always incremental on a Fanuc",
    "G91.1": "arc centres are always incremental on a Fanuc (no G91.1 code)",
    "G8": "LinuxCNC lathe radius mode",
}
_LINUXCNC_M = (48, 49, 50, 51, 52, 53, 60, 61, 62, 63, 64, 65)

DIALECT = Dialect(
    name="fanuc",
    title="Fanuc",
    protocol="fanuc",
    g_codes=COMMON_G | {290},  # G29
    m_codes=COMMON_M,
    dwell_p_ms=True,
    home_all_axes=False,
    g10_l=(2, 1, 10, 11, 12, 13),
    g10_p_range=(1, 6),  # the external offset P0 is not supported
    g10_incremental=True,
    g10_tool_table=False,
    lines=LineRules(
        semicolon=Answer(
            "alarm", "';' is the end of block on a Fanuc: what follows is read as a new block"
        ),
        lower_case=Answer("alarm", "lower-case address letters are not ISO tape code on a Fanuc"),
        refused_g={
            w: Answer(_IMPROPER, f"improper G-code ({why})") for w, why in _REFUSED_G.items()
        },
        refused_m={m: Answer("alarm", f"M{m} is a LinuxCNC M-code, not a Fanuc one")
                   for m in _LINUXCNC_M},  # fmt: skip
        program_number_max=9999,
        sequence_number_max=99999,
        least_increments=True,
    ),
    post=PostRules(
        keeps_tape=True,
        iso_words=True,
        paren_comments=True,
        g80_with_motion=True,
        g29=True,
        absolute_arc_centres=False,
        g91_1=False,
        dwell_word="X",
    ),
)
