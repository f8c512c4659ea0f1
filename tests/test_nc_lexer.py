"""The two lexer paths (fast block_words, layout-keeping tokenize) accept the same language and
agree on the words; tokenize loses no character."""

from __future__ import annotations

from hypothesis import example, given, settings
from hypothesis import strategies as st

from planning.nc import NCError, block_words, line_error, tokenize

ALPHABET = "GXYZFgxyzMN0123456789.-+ \t()/;%#Ä\r"


@settings(max_examples=1000, deadline=None)
@example(";\x00")  # a NUL inside a comment: valid, once refused by the fast path
@example(";\n0")  # a line break inside a ';' comment: the two paths once disagreed
@given(st.text(alphabet=ALPHABET, max_size=25) | st.text(max_size=25))
def test_fast_and_layout_paths_agree(raw):
    toks = tokenize(raw)
    assert "".join(t.text for t in toks) == raw
    try:
        words, flag = block_words(raw, "f.nc", 7)
    except NCError as err:
        assert err.line == 7 and 1 <= err.column <= len(raw) + 1
        bad = line_error(raw, "f.nc", 7)
        assert (bad.column, bad.word) == (err.column, err.word)
        assert bad.reason != "unreadable block"  # the error path always finds the cause
        return
    # accepted: every token is space, comment, word, and at most one leading / or a lone %
    assert all(t.kind != "bad" for t in toks)
    assert words == [(t.letter, t.number) for t in toks if t.kind == "word"]
    code = [t for t in toks if t.kind in ("word", "delete", "percent")]
    assert flag == (
        2 if code and code[0].kind == "percent" else 1 if code and code[0].kind == "delete" else 0
    )


def test_examples():
    assert block_words("g1x10y-2.5f300", "f", 1) == (
        [("G", "1"), ("X", "10"), ("Y", "-2.5"), ("F", "300")],
        0,
    )
    assert block_words("/N10 G0 X.5 (c) ; d", "f", 1) == ([("N", "10"), ("G", "0"), ("X", ".5")], 1)
    assert block_words(" % (tape)", "f", 1) == ([], 2)
    assert block_words("X 10.", "f", 1) == ([("X", "10.")], 0)


def test_a_comment_separates_words_not_a_letter_from_its_number():
    assert block_words("X1(c)Y2", "f", 1) == ([("X", "1"), ("Y", "2")], 0)
    for raw in ("F()0", "G1 X (c) 1", "X1(c)\x00"):
        try:
            block_words(raw, "f", 1)
        except NCError as err:
            bad = line_error(raw, "f", 1)
            assert (err.column, err.word, err.reason) == (bad.column, bad.word, bad.reason)
        else:
            raise AssertionError(f"{raw!r} accepted")
