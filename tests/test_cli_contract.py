"""The command contract: every command has help, and bad input files end in one clear line.

Each command that reads a file is fed a missing file, an empty file, binary junk, text junk and a
valid file of another kind; each must exit with status 2 and a ``cutlab: error:`` message that
names the file, never a traceback.
"""

from __future__ import annotations

import argparse

import pytest

from rig.cli import build_parser, main


def _commands() -> list[list[str]]:
    out: list[list[str]] = []

    def walk(parser: argparse.ArgumentParser, prefix: list[str]) -> None:
        for a in parser._actions:
            if isinstance(a, argparse._SubParsersAction):
                for name, sp in a.choices.items():
                    walk(sp, [*prefix, name])
                return
        out.append(prefix)

    walk(build_parser(), [])
    return out


COMMANDS = _commands()


def test_the_contract_commands_exist() -> None:
    names = {" ".join(c) for c in COMMANDS}
    for want in [
        "demo",
        "nc check",
        "nc motions",
        "nc plot",
        "daq record",
        "data info",
        "data plot",
        "dnc send",
        "dnc sim-controller",
        "campaign run",
        "analyze forces",
        "analyze modal",
        "rules derive",
        "rules list",
        "rules show",
        "plan rough",
        "plan feed",
        "plan orient",
    ]:
        assert want in names, f"`cutlab {want}` is missing"


@pytest.mark.parametrize("cmd", COMMANDS, ids=lambda c: " ".join(c))
def test_every_command_has_help(cmd: list[str], capsys) -> None:
    with pytest.raises(SystemExit) as ei:
        main([*cmd, "--help"])
    assert ei.value.code == 0
    assert "usage: cutlab" in capsys.readouterr().out


# Commands and how to call them with FILE as their main input (plus required options).
FILE_COMMANDS = {
    "nc check": ["nc", "check", "{f}"],
    "nc motions": ["nc", "motions", "{f}", "--csv"],
    "nc plot": ["nc", "plot", "{f}", "-o", "{tmp}/p.png"],
    "data info": ["data", "info", "{f}"],
    "data plot": ["data", "plot", "{f}", "-o", "{tmp}/d.png"],
    "analyze forces": ["analyze", "forces", "{f}"],
    "analyze modal": ["analyze", "modal", "{f}"],
    "rules derive": ["rules", "derive", "{f}", "-o", "{tmp}/r.toml"],
    "rules show": ["rules", "show", "{f}", "--db", "{tmp}/rb.sqlite"],
    "campaign run": ["campaign", "run", "{f}", "--dry-run"],
    "plan rough": ["plan", "rough", "{f}", "-o", "{tmp}/r.nc"],
    "plan orient": ["plan", "orient", "{f}", "-o", "{tmp}/orient"],
    "plan feed (program)": [
        "plan",
        "feed",
        "{f}",
        "--rules",
        "{tmp}/none.toml",
        "-o",
        "{tmp}/o.nc",
    ],
    "plan simulate": ["plan", "simulate", "{f}", "--tool", "phi10-flat"],
    "dnc send": ["dnc", "send", "{f}", "--port", "loop://", "--protocol", "grbl"],
}

BAD_FILES = {
    "missing": None,
    "empty": b"",
    "binary": bytes(range(256)) * 8,
    "text": b"hello world\nthis is not what you think\n",
    "hdf5-foreign": "hdf5",
    "toml-foreign": b"[something]\nelse = 1\n",
}


def _make(kind: str, tmp_path, ext: str):
    p = tmp_path / f"input-{kind}{ext}"
    data = BAD_FILES[kind]
    if data is None:
        return p
    if data == "hdf5":
        import h5py

        with h5py.File(p, "w") as f:
            f["x"] = [1, 2, 3]
        return p
    p.write_bytes(data)
    return p


EXT = {
    "nc": ".nc",
    "data": ".h5",
    "analyze": ".h5",
    "rules": ".h5",
    "campaign": ".toml",
    "plan rough": ".toml",
    "plan orient": ".toml",
    "rules show": ".toml",
}


@pytest.mark.parametrize("kind", list(BAD_FILES))
@pytest.mark.parametrize("name", list(FILE_COMMANDS))
def test_bad_input_file_is_one_clear_error(name: str, kind: str, tmp_path, capsys) -> None:
    ext = EXT.get(name) or EXT.get(" ".join(name.split()[:2])) or EXT.get(name.split()[0], ".nc")
    f = _make(kind, tmp_path, ext)
    argv = [a.format(f=f, tmp=tmp_path) for a in FILE_COMMANDS[name]]
    code = main(argv)
    err = capsys.readouterr().err
    if kind == "empty" and name in ("nc check", "nc motions", "nc plot"):
        assert code == 0, err  # an empty program is a valid program of no blocks
        return
    assert code == 2, f"exit {code}, stderr: {err[-500:]}"
    assert err.startswith("cutlab: error:"), err[-500:]
    assert "Traceback" not in err
    assert f.name in err or str(tmp_path) in err, f"the message does not name the file: {err}"


def test_a_reader_that_stops_early_ends_the_command_quietly(tmp_path) -> None:
    """`cutlab nc motions big.nc | head -2`: exit 141 (SIGPIPE's), no traceback."""
    import subprocess
    import sys

    prog = tmp_path / "big.nc"
    prog.write_text("G21 G90 G1 F100\n" + "".join(f"G1 X{i % 50} Y{i % 7}\n" for i in range(20000)))
    proc = subprocess.Popen(
        [sys.executable, "-c", "from rig.cli import main; import sys; sys.exit(main())",
         "nc", "motions", str(prog), "--csv"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    assert proc.stdout.readline().startswith(b"line,block,kind")
    proc.stdout.close()  # what `head` does after its lines
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141, err
    assert "Traceback" not in err
