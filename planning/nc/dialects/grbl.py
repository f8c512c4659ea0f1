"""GRBL 1.1h (gnea/grbl), modelled on its source (:mod:`planning.nc.grbl`).

Interpretation: what GRBL 1.1 answers ``error:20`` to of what the interpreter knows is refused
(an error; lenient: a warning): cutter compensation G41/G42, G43 (it has only G43.1, Z only),
canned cycles G81-G83 and their return modes G98/G99, absolute arc centres G90.1, path modes
other than G61 (G64), G52, tool change M6, and the O, D, H, Q and A/B/C words (a line holding
only an O number is stripped by the sender). G4 P in seconds (G4 X too); G10 L2/L20 with P0..P6;
G28/G30 with no axis word move all axes; G28.1/G30.1 store the point; G29 is answered with an
error; G38.2..G38.5 probe; the machine's arc radius tolerance ($12).

Line answers: the firmware model (:mod:`planning.nc.grbl`): line buffer, real-time characters,
block delete, error codes.

Output: no ``%``, O, blank or block-delete lines; no M6 unless a tool changer (an M0 pause names
the tool), no G43/H, D, G64, G98/G99; canned cycles and G29 expanded; G90.1 becomes G91.1 with
the centres rewritten; 79 characters a line (comments moved to lines of their own); the written
program is checked by the firmware model; streamed by ``rig.dnc``'s GRBL protocol.
"""

from __future__ import annotations

from planning.nc._codes import COMMON_G, COMMON_M
from planning.nc.dialects.base import Dialect, PostRules
from planning.nc.grbl import GRBL_LINE_CHARS

DIALECT = Dialect(
    name="grbl",
    title="GRBL",
    protocol="grbl",
    # G29 (refused with its own message below), G28.1/G30.1, G43.1, G38.2..G38.5
    g_codes=COMMON_G | {290, 281, 301, 431, 382, 383, 384, 385},
    m_codes=COMMON_M,
    refused_g=frozenset({410, 420, 430, 810, 820, 830, 980, 990, 901, 640, 520}),
    refused_m=frozenset({6}),
    refused_letters=frozenset("ODHQABC"),
    refusal_name="GRBL 1.1",
    strips_lone_o=True,
    code_errors={290: "G29 is not a GRBL command"},
    cutter_comp=False,
    g10_l=(2, 20),
    g10_p_range=(0, 6),
    g43_1_z_only=True,
    firmware_model=True,
    max_line_chars=GRBL_LINE_CHARS,
    post=PostRules(
        absolute_arc_centres=False,
        canned_cycles=False,
        drops_blank_and_deleted=True,
        full_words=False,
        firmware_check=True,
    ),
)
