"""EIA RS-244 tape code, for controls set to EIA instead of ISO.

EIA punches each character in 8 tape channels with odd parity in channel 5 (0x10): digits in
channels 1-4 (1 = 0x01 ... 9 = 0x19, 0 = 0x20), letters in three zones (A-I 0x6_, J-R 0x4_, S-Z
0x2_), end of block in channel 8 alone (0x80), rewind stop / end of record (ER, ``%`` in ISO) =
0x0B, control out/in (the comment parentheses) = channels 2-4-5 (0x1A) and 2-4-7 (0x4A). Every
code has an odd number of holes; blank tape (0x00) and delete (0x7F) are ignored by the reader.
On the wire each code is one 8-bit character, so the line runs 8 data bits without UART parity.

Characters EIA has no code for (``#``, ``=``, ``*``, ``[``, lower case, ...) cannot be sent in EIA.
"""

from __future__ import annotations

from rig.dnc.errors import DncError

EOB = 0x80
ER = 0x0B  # end of record / rewind stop, what ISO writes as '%'
BLANK = 0x00
DELETE = 0x7F

_DIGITS = {"1": 0x01, "2": 0x02, "3": 0x13, "4": 0x04, "5": 0x15, "6": 0x16, "7": 0x07,
           "8": 0x08, "9": 0x19, "0": 0x20}  # fmt: skip
_ZONES = ((0x60, "ABCDEFGHI"), (0x40, "JKLMNOPQR"), (0x20, "STUVWXYZ"))


def _odd(code: int) -> int:
    """Set channel 5 so the code has an odd number of holes."""
    return code if bin(code).count("1") % 2 else code | 0x10


def _letters() -> dict[str, int]:
    out = {}
    for zone, letters in _ZONES:
        first = 2 if zone == 0x20 else 1  # S is 2 in its zone: zone 0x20 with 1 would be '/'
        for i, ch in enumerate(letters):
            out[ch] = _odd(zone | (first + i))
    return out


#: ASCII character -> EIA code
ENCODE: dict[str, int] = {
    **{d: _odd(c) for d, c in _DIGITS.items()},
    **_letters(),
    " ": 0x10,
    "+": 0x70,
    "-": 0x40,
    ".": 0x6B,
    "/": 0x31,
    ",": 0x3B,
    "(": 0x1A,
    ")": 0x4A,
    "\t": 0x3E,
}
#: EIA code -> ASCII character
DECODE: dict[int, str] = {v: k for k, v in ENCODE.items()}


def has_odd_parity(code: int) -> bool:
    return bin(code).count("1") % 2 == 1


def encode(text: str, where: str) -> bytes:
    """``text`` (one block, without end of block) in EIA; DncError naming the column otherwise."""
    out = bytearray()
    for col, ch in enumerate(text, 1):
        code = ENCODE.get(ch)
        if code is None:
            raise DncError(
                f"{where}:{col}: character {ch!r} has no EIA code (EIA has digits, A-Z, space "
                "+ - . / , ( ) and tab); send the program in ISO"
            )
        out.append(code)
    return bytes(out)


def decode(data: bytes) -> str:
    """EIA codes -> ASCII (blank and delete dropped); KeyError for a code EIA does not have."""
    return "".join(DECODE[b] for b in data if b not in (BLANK, DELETE))
