"""G- and M-code tables of the interpreter (private).

G-codes are keyed by ten times their number so ``G90.1`` (901) and ``G91.1`` (911) are distinct
integers; groups follow RS-274 numbering (0 = non-modal), except that G80 has a group of its own
(9, as on Fanuc) so the common ``G80 G0 Z..`` is legal: it cancels the cycle, then G0 applies.
"""

from __future__ import annotations

INCH_MM = 25.4  # mm per inch (G20)

# G-code (times 10, so G90.1 is 901) -> modal group (RS-274 numbering; 0 = non-modal)
G_GROUP = {
    0: 1, 10: 1, 20: 1, 30: 1, 810: 1, 820: 1, 830: 1,
    800: 9,
    40: 0, 280: 0, 290: 0, 300: 0, 530: 0,
    170: 2, 180: 2, 190: 2,
    900: 3, 910: 3,
    901: 4, 911: 4,
    930: 5, 940: 5,
    200: 6, 210: 6,
    400: 7, 410: 7, 420: 7,
    430: 8, 490: 8,
    980: 10, 990: 10,
    540: 12, 550: 12, 560: 12, 570: 12, 580: 12, 590: 12,
}  # fmt: skip
MOTION_MODE = {0: 0, 10: 1, 20: 2, 30: 3, 800: 80, 810: 81, 820: 82, 830: 83}
M_GROUP = {0: "stop", 1: "stop", 2: "stop", 30: "stop", 3: "spindle", 4: "spindle",
           5: "spindle", 6: "tool change", 7: "coolant", 8: "coolant", 9: "coolant"}  # fmt: skip
KNOWN_M = set(M_GROUP)
# What GRBL 1.1 refuses (error:20) of what this interpreter knows: cutter compensation, G43 (it
# has only G43.1), canned cycles and their return modes, absolute arc centres, tool change, and
# the O, D, H, Q and rotary words (3 axes).
GRBL_UNSUPPORTED_G = frozenset({410, 420, 430, 810, 820, 830, 980, 990, 901})
GRBL_UNSUPPORTED_M = frozenset({6})
GRBL_UNSUPPORTED_LETTERS = frozenset("ODHQABC")
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
