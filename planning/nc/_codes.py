"""G- and M-code tables of the interpreter (private).

G-codes are keyed by ten times their number so ``G90.1`` (901) and ``G91.1`` (911) are distinct
integers; groups follow RS-274 numbering (0 = non-modal), except that G80 has a group of its own
(9, as on Fanuc) so the common ``G80 G0 Z..`` is legal: it cancels the cycle, then G0 applies.

Some codes exist on some controls only (:data:`SPECIFIC_G`, :data:`SPECIFIC_M`): each dialect of
:mod:`planning.nc.dialects` says which it knows; on the others they are unknown codes, as on the
real control. :data:`COMMON_G` and :data:`COMMON_M` are the codes every dialect starts from.
"""

from __future__ import annotations

INCH_MM = 25.4  # mm per inch (G20)

# G-code (times 10, so G90.1 is 901) -> modal group (RS-274 numbering; 0 = non-modal)
G_GROUP = {
    0: 1, 10: 1, 20: 1, 30: 1, 382: 1, 383: 1, 384: 1, 385: 1, 810: 1, 820: 1, 830: 1,
    800: 9,
    40: 0, 100: 0, 280: 0, 281: 0, 290: 0, 300: 0, 301: 0, 520: 0, 530: 0,
    920: 0, 921: 0, 922: 0, 923: 0,
    170: 2, 180: 2, 190: 2,
    900: 3, 910: 3,
    901: 4, 911: 4,
    930: 5, 940: 5,
    200: 6, 210: 6,
    400: 7, 410: 7, 420: 7,
    430: 8, 431: 8, 490: 8,
    980: 10, 990: 10,
    540: 12, 550: 12, 560: 12, 570: 12, 580: 12, 590: 12, 591: 12, 592: 12, 593: 12,
    610: 13, 611: 13, 640: 13,
    970: 14,
    80: 15,
}  # fmt: skip
# codes some controls have and others do not (each dialect module lists the ones it knows): G29,
# G28.1/G30.1, G61.1, G92.2/G92.3, G59.1..G59.3, G97, G8 (lathe radius mode), G43.1, G38.2..G38.5
SPECIFIC_G = frozenset({290, 281, 301, 611, 922, 923, 591, 592, 593, 970, 80, 431,
                        382, 383, 384, 385})  # fmt: skip
COMMON_G = frozenset(G_GROUP) - SPECIFIC_G
# (G38.2..G38.5 all probe alike offline: mode 38)
MOTION_MODE = {0: 0, 10: 1, 20: 2, 30: 3, 382: 38, 383: 38, 384: 38, 385: 38, 800: 80, 810: 81,
               820: 82, 830: 83}  # fmt: skip
# work offset G code key -> index in ModalState.work_offsets_mm (LinuxCNC's P1..P9 minus one)
OFFSET_INDEX = {540: 0, 550: 1, 560: 2, 570: 3, 580: 4, 590: 5, 591: 6, 592: 7, 593: 8}
OFFSET_CODES: tuple[int | float, ...] = (54, 55, 56, 57, 58, 59, 59.1, 59.2, 59.3)
M_GROUP = {0: "stop", 1: "stop", 2: "stop", 30: "stop", 60: "stop", 3: "spindle", 4: "spindle",
           5: "spindle", 6: "tool change", 61: "tool change", 7: "coolant", 8: "coolant",
           9: "coolant", 48: "override", 49: "override", 50: "override", 51: "override",
           52: "override", 53: "override", 62: "output", 63: "output", 64: "output",
           65: "output"}  # fmt: skip
KNOWN_M = set(M_GROUP)
# overrides M48-M53, pallet stop M60, M61 Q (set the tool number without a change) and digital
# outputs M62-M65 P: some controls only
SPECIFIC_M = frozenset({48, 49, 50, 51, 52, 53, 60, 61, 62, 63, 64, 65})
COMMON_M = frozenset(KNOWN_M) - SPECIFIC_M
LETTERS = frozenset("ABCDFHIJKLNOPQRSTXYZ")
LETTERS_GM = LETTERS | {"G", "M"}
FAST_LETTERS = frozenset("XYZFN")  # blocks with only these words skip the general word checks
_GKEY: dict[str, int] = {}  # number text -> G key cache (programs repeat the same few)


def gkey(num: str) -> int:
    k = _GKEY.get(num)
    if k is None:
        k = round(float(num) * 10.0)
        if len(_GKEY) < 4096:
            _GKEY[num] = k
    return k


def gname(key: int) -> str:
    return f"G{key // 10}" if key % 10 == 0 else f"G{key / 10:g}"


def offset_code(index: int) -> int | float:
    """G code number of work offset ``index`` (0 -> 54, 6 -> 59.1)."""
    return OFFSET_CODES[index]
