"""What `dnc send --dry-run` shows: the restart preamble and the first blocks of a send, as the
protocol sends them; nothing is opened or sent."""

from __future__ import annotations

from analysis.validation import JsonObject, JsonValue
from rig.dnc.connect import SendJob

__all__ = ["DRY_RUN_BLOCKS", "preview", "preview_lines"]

#: blocks of the program shown after the preamble
DRY_RUN_BLOCKS = 10


def preview(job: SendJob) -> JsonObject:
    """The send's first items: ``preamble`` (restart lines) and ``first_blocks``."""
    items = job.items_to_send()
    pre: list[JsonValue] = [it.text for it in items if it.block < 0]
    first = [it for it in items if it.block >= 0][:DRY_RUN_BLOCKS]
    blocks: list[JsonValue] = [
        {"block": it.block, "line": it.line, "text": it.text} for it in first
    ]
    return {"dry_run": True, "program": job.program.name, "protocol": job.protocol,
            "start_block": job.start_block, "restart": list(job.restart_notes),
            "preamble": pre, "first_blocks": blocks, "sent": False}  # fmt: skip


def preview_lines(p: JsonObject) -> list[str]:
    """The preview as text: the preamble, then each block with its number and line."""
    pre, blocks = p["preamble"], p["first_blocks"]
    assert isinstance(pre, list) and isinstance(blocks, list)
    out = [f"(restart preamble: {len(pre)} lines)", *map(str, pre)] if pre else []
    out.append(f"(then the program from block {p['start_block']}, first {len(blocks)} blocks)")
    for b in blocks:
        assert isinstance(b, dict)
        out.append(f"{b['text']}    (block {b['block']}, line {b['line']})")
    return out
