"""The campaign runner: a campaign TOML -> one NC program and one HDF5 run file per test.

A campaign (see :mod:`rig.campaign.config` for the file) names the machine, tool, material, rig
(``sim`` or ``real``), DAQ and dynamometer settings and a test matrix. :func:`run_campaign` plans
every test (program generated and checked by the NC parser before anything runs), then runs them
in order on the rig, each through :func:`rig.campaign.run.execute_run`, and keeps a manifest::

    <output_dir>/<campaign name>/
        campaign.json           manifest: config hash, software version, every run's status
        campaign.toml           the campaign file as run
        runs/NNN-<test name>.h5 one run file per test (layout: analysis.runs.layout)
        programs/NNN-<test name>.nc
        tap/tap_x.csv, tap_y.csv  the tool's impulse-hammer records ([tap_test]), before the cuts
        report/                 written by rig.report.base after the campaign

Resume: running a campaign again skips every test whose run file closed with status
``success`` (also when the runner was stopped before its manifest said so); a run that ended in
abort or fail, or whose process was killed (the file reads
``interrupted``), is run again and its earlier file is kept beside it as ``.attempt-K.h5``. A lock
file stops two runners from writing one campaign. A campaign whose inputs changed since its runs
were recorded (config, tool, material, machine, rig, a program) is not resumed: ``fresh`` moves the
earlier runs aside and starts over, ``force_resume`` resumes and records the change. A run does not
start without room on the disk for its expected size plus the writer's margin, and one whose disk
runs low or fails ends ``fail`` with the reason (see :mod:`rig.log.writer`).

Each run file records the conditions, tool, material, machine, calibration identity, the NC
program and its SHA-256, the software version, every block with its send time, events (zero,
pause, overflow, interlock, ...) and the exit status with its reason.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

from analysis import __version__
from analysis.config import ToolMode
from analysis.errors import ConfigError
from analysis.forces import FACEMILL
from analysis.runs import file as rf
from rig.campaign.chatter_watch import ChatterWatchConfig
from rig.campaign.config import Campaign, RunConditions, load_campaign
from rig.campaign.manifest import (
    Manifest,
    campaign_lock,
    finished,
    lock_holder,
    run_status,
    set_aside,
    start_fresh,
    utc_now,
)
from rig.campaign.plan import PlannedRun, _dialect, plan_campaign
from rig.campaign.results import CampaignResult, CampaignStatus, RunRecord, StatusRow
from rig.campaign.run import RigSession, RunConfig, StopRequest, Suspenders, execute_run
from rig.daq import Calibration
from rig.errors import RigError

__all__ = [
    "Campaign",
    "CampaignResult",
    "PlannedRun",
    "RunRecord",
    "campaign_folder",
    "campaign_status",
    "load_campaign",
    "plan_campaign",
    "run_campaign",
    "run_status",
]


def campaign_folder(campaign: Campaign, out_root: str | Path | None = None) -> Path:
    root = Path(out_root) if out_root is not None else Path(campaign.spec.campaign.output_dir)
    if not root.is_absolute() and out_root is None:
        root = Path.cwd() / root
    return root / campaign.name


def campaign_status(campaign: Campaign, out_root: str | Path | None = None) -> CampaignStatus:
    """Where the campaign's folder is and each planned run's status and reason there (a run
    without a file is ``missing``)."""
    folder = campaign_folder(campaign, out_root)
    rows: list[StatusRow] = []
    for p in plan_campaign(campaign):
        st, reason = run_status(folder / "runs" / f"{p.file_stem}.h5")
        rows.append({"run": p.test.index, "name": p.test.name, "status": st, "reason": reason})
    _note_interrupted(folder, campaign, rows)
    return {"campaign": campaign.name, "folder": str(folder), "runs": rows}


def _note_interrupted(folder: Path, campaign: Campaign, rows: list[StatusRow]) -> None:
    """A manifest still saying ``running`` for a run whose runner is gone says ``interrupted``."""
    if not (folder / "campaign.json").exists() or lock_holder(folder) is not None:
        return
    manifest = Manifest(folder, campaign)
    for r in rows:
        entry = manifest.entry(r["name"])
        if entry and entry.get("status") == rf.STATUS_RUNNING:
            manifest.set(r["name"], status=rf.STATUS_INTERRUPTED, reason=r["reason"])


# ----------------------------------------------------------------------------------------------
# Running
# ----------------------------------------------------------------------------------------------

SessionFactory = Callable[[Campaign, PlannedRun, int], RigSession]
#: How a writer's failure for want of room starts (rig.log.writer).
_NO_ROOM = ("disk full", "disk nearly full", "file size limit")


def default_session_factory(campaign: Campaign) -> SessionFactory:
    if campaign.spec.campaign.rig == "sim":
        from rig.sim import sim_session

        return sim_session
    from rig.campaign.real import real_session

    return real_session


def _run_config(campaign: Campaign, plan: PlannedRun) -> RunConfig:
    """The run's suspenders, chatter watch and timing from the campaign's config."""
    spec, sus = campaign.spec, campaign.spec.suspenders
    return RunConfig(
        Suspenders(sus.force_limit_n, sus.on_force, sus.hold_timeout_s, sus.on_overflow,
                   sus.watchdog_wall_s),
        ChatterWatchConfig(sus.on_chatter, plan.test.spindle_rpm, sus.chatter_floor_n,
                           spec.chatter.settings()),
        zero_s=spec.daq.rest_s, expected_s=plan.expected_s,
        sim_speed=spec.sim.speed if spec.campaign.rig == "sim" else 1.0,
    )  # fmt: skip


def _conditions(campaign: Campaign, plan: PlannedRun) -> dict[str, Any]:
    t = plan.test
    c = campaign.spec.campaign
    return {
        **t.as_dict(),
        "campaign": campaign.name,
        "program_kind": campaign.spec.program.kind,
        "tool": c.tool,
        "tool_spec": campaign.tool.model_dump(),
        "tool_kind": "facemill" if FACEMILL.describes(campaign.tool) else campaign.tool.kind,
        "teeth": campaign.teeth,
        "material": c.material,
        "machine": campaign.machine.name,
        "block": asdict(plan.cut.block),
        "z_cut_mm": plan.cut.z_cut_mm,
        "y_path_mm": plan.cut.y_path_mm,
        # For the identification: the block's centre line seen from the cutter axis (face
        # mill), and the milling mode of an end mill (a full slot, or down milling a width).
        "center_offset_mm": -plan.cut.y_path_mm,
        "mode": "slot" if t.width_mm >= campaign.tool.diameter_mm - 1e-9 else "down",
        "program_sha256": plan.sha256,
        "software_version": __version__,
        "operator": c.operator,
    }


def _rig_meta(campaign: Campaign, session: RigSession) -> dict[str, Any]:
    dyno = campaign.rig.dynamometer
    meta: dict[str, Any] = {
        "rig": campaign.spec.campaign.rig,
        "machine": campaign.machine.name,
        "controller": _dialect(campaign),
        "dynamometer": dyno.model,
        "calibration_id": dyno.calibration_id,
        "channels": [ch.name for ch in dyno.channels],
        "daq_device": session.daq.info.device,
        "daq_rate_hz": session.daq.info.rate_hz,
        "modes": [m.model_dump() for m in dyno.modes],
    }
    if campaign.spec.campaign.rig == "sim":
        meta["sim"] = campaign.spec.sim.model_dump()
        m = campaign.material
        meta["sim_truth"] = {
            "facemill": m.facemill.model_dump() if m.facemill else None,
            "endmill": m.endmill.model_dump() if m.endmill else None,
        }
    return meta


@contextlib.contextmanager
def _sigint_to(stop: StopRequest) -> Iterator[None]:
    """Ctrl-C asks for a safe stop (feed hold, then resume or abort) instead of a traceback;
    SIGTERM and a second Ctrl-C stop without asking."""
    if threading_main() is False:
        yield
        return

    def on_int(signum: int, frame: object) -> None:
        stop.request(kill=stop.event.is_set(), source="Ctrl-C")
        print("\ncutlab: stopping safely (feed hold) ...", file=sys.stderr, flush=True)

    def on_term(signum: int, frame: object) -> None:
        stop.request(kill=True, source="SIGTERM")

    old_int = signal.signal(signal.SIGINT, on_int)
    old_term = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)


def threading_main() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def run_campaign(
    campaign: Campaign,
    *,
    out_root: str | Path | None = None,
    session_factory: SessionFactory | None = None,
    progress: bool = True,
    stop: StopRequest | None = None,
    only: Callable[[RunConditions], bool] | None = None,
    fresh: bool = False,
    force_resume: bool = False,
) -> CampaignResult:
    """Run (or resume) a campaign; returns every run's status. See the module docstring.

    ``fresh``: move an earlier run of the campaign aside (``before-<utc>/``) and start over;
    ``force_resume``: resume although inputs changed (the change is recorded in the manifest).
    """

    plans = plan_campaign(campaign)
    _check_ready(campaign, session_factory)
    folder = campaign_folder(campaign, out_root)
    (folder / "runs").mkdir(parents=True, exist_ok=True)
    (folder / "programs").mkdir(exist_ok=True)
    factory = session_factory or default_session_factory(campaign)
    stop = stop or StopRequest()
    records: list[RunRecord] = []
    wall0 = time.monotonic()
    stopped = False
    cal_sheet = Calibration.from_dynamometer(campaign.rig.dynamometer)
    sus = campaign.spec.suspenders
    bar = _campaign_bar(len(plans), progress, campaign.name)
    daq_rate_hz = campaign.spec.daq.rate_hz or campaign.rig.daq.rate_hz
    bytes_per_s = daq_rate_hz * len(campaign.rig.dynamometer.channels) * 8  # float64 bound
    with campaign_lock(folder), _sigint_to(stop):
        if fresh and start_fresh(folder) is not None:
            (folder / "runs").mkdir()
            (folder / "programs").mkdir()
        manifest = Manifest(folder, campaign)
        changes = manifest.changed_inputs({p.test.name: p.sha256 for p in plans})
        if changes and not force_resume:
            raise RigError(_changed_message(campaign, folder, changes))
        manifest.accept_inputs(changes)
        (folder / "campaign.toml").write_text(campaign.text)
        tap_records(campaign, folder)
        for k, plan in enumerate(plans):
            t = plan.test
            if only is not None and not only(t):
                continue
            path = folder / "runs" / f"{plan.file_stem}.h5"
            entry = manifest.entry(t.name)
            if finished(folder, entry, plan.file_stem, plan.sha256):
                if entry is not None and entry.get("status") != rf.STATUS_SUCCESS:
                    why = "closed before the runner was stopped (resume)"
                    manifest.set(t.name, status=rf.STATUS_SUCCESS, ended_utc=utc_now(), reason=why)
                records.append(
                    RunRecord(t.index, t.name, t.group, str(path), rf.STATUS_SUCCESS,
                              "finished earlier (resume)", skipped=True)
                )  # fmt: skip
                bar.update(1)
                continue
            if stopped or stop.event.is_set():
                break
            rec = _run_one(campaign, plan, k, folder, manifest, factory, stop, cal_sheet, bar,
                           bytes_per_s)  # fmt: skip
            records.append(rec)
            status, reason = rec.status, rec.reason
            bar.update(1)
            if status != rf.STATUS_SUCCESS:
                bar.write(f"cutlab: run {t.index} {t.name}: {status}: {reason}", file=sys.stderr)
            if stop.event.is_set() or (status == rf.STATUS_FAIL and sus.stop_campaign_on_fail):
                stopped = True
        manifest.data["last_ended_utc"] = utc_now()
        manifest.save()
    bar.close()
    counts: dict[str, int] = {}
    for r in records:
        counts[r.status] = counts.get(r.status, 0) + 1
    stopped = stopped or len(records) < sum(1 for p in plans if only is None or only(p.test))
    return CampaignResult(
        campaign.name, folder, tuple(records), stopped, time.monotonic() - wall0, counts
    )


def _check_ready(campaign: Campaign, session_factory: SessionFactory | None) -> None:
    """Refuse before anything runs: an [adaptive] table the controller cannot serve, a real rig
    whose hardware is not ready."""
    if campaign.spec.adaptive is not None:
        from rig.adaptive.session import check_adaptive

        check_adaptive(campaign)  # refused before anything runs
    if campaign.spec.campaign.rig == "real" and session_factory is None:
        from rig.campaign.real import check_hardware

        _, problems = check_hardware(campaign)
        if problems:
            raise RigError(
                f"{campaign.path}: rig = 'real' but the hardware is not ready:\n  "
                + "\n  ".join(problems)
            )


def _run_one(
    campaign: Campaign, plan: PlannedRun, k: int, folder: Path, manifest: Manifest,
    factory: SessionFactory, stop: StopRequest, cal_sheet: Calibration, bar: Any,
    bytes_per_s: float,
) -> RunRecord:  # fmt: skip
    """Run test ``k`` of the plan into its run file, the manifest kept up to date."""
    from rig.log import RunWriter, RunWriterError, free_space_problem

    t = plan.test
    path = folder / "runs" / f"{plan.file_stem}.h5"
    rest_s = 2 * campaign.spec.daq.rest_s + 10.0
    problem = free_space_problem(folder / "runs", bytes_per_s * (plan.expected_s + rest_s))
    if problem:
        raise RigError(f"run {t.index} ({t.name}) not started: {problem}")
    earlier = set_aside(path)
    (folder / "programs" / f"{plan.file_stem}.nc").write_text(plan.program_text)
    session = factory(campaign, plan, k)
    if campaign.spec.adaptive is not None:  # GRBL overrides from the live force
        from rig.adaptive.session import adaptive_session

        session = adaptive_session(campaign, t, session, cal_sheet)
    from rig.dnc import program_from_text

    program = program_from_text(plan.program_text, f"{plan.file_stem}.nc", check_nc=False)
    manifest.set(
        t.name, index=t.index, group=t.group, file=str(path.relative_to(folder)),
        status=rf.STATUS_RUNNING, reason="", started_utc=utc_now(),
        earlier_attempt=str(earlier.name) if earlier else None,
        conditions=t.as_dict(), program_sha256=plan.sha256,
    )  # fmt: skip
    writer = RunWriter(path, session.daq.info, cal_sheet, clock=session.clock)
    try:
        writer.set_conditions(_conditions(campaign, plan))
        writer.set_rig(_rig_meta(campaign, session))
        writer.set_program(plan.program_text, f"{plan.file_stem}.nc")
        bar.set_postfix_str(t.name[:40])
        outcome = execute_run(session, program, writer, cal_sheet, _run_config(campaign, plan),
                              stop, _within_run(bar, t.name))  # fmt: skip
        status, reason = outcome.status, outcome.reason
    except BaseException as exc:
        status, reason = rf.STATUS_FAIL, f"{type(exc).__name__}: {exc}"[:400]
        with contextlib.suppress(RunWriterError):
            writer.close(status, reason)
        manifest.set(t.name, status=status, reason=reason, ended_utc=utc_now())
        raise
    try:
        writer.close(status, reason)
    except RunWriterError as exc:  # the medium failed after the program ended
        status, reason = rf.STATUS_FAIL, str(exc)
    if writer.failure is not None and status == rf.STATUS_SUCCESS:
        status, reason = rf.STATUS_FAIL, writer.failure
    manifest.set(
        t.name, status=status, reason=reason, ended_utc=utc_now(),
        peak_force_n=outcome.peak_force_n, wall_s=round(outcome.wall_s, 3),
    )  # fmt: skip
    if writer.failure is not None and writer.failure.startswith(_NO_ROOM):
        # no room for the next run either: stop here, in one line, files closed
        raise RigError(f"run {t.index} ({t.name}) stopped: {writer.failure}; free some "
                       "space and run the same command again to resume")  # fmt: skip
    return RunRecord(t.index, t.name, t.group, str(path), status, reason, False,
                     outcome.peak_force_n, outcome.wall_s)  # fmt: skip


def tap_records(campaign: Campaign, folder: Path) -> dict[str, Path]:
    """The tool's tap-test records per direction in ``folder/tap/`` ([tap_test]; none without
    one): the simulated rig taps the twin's tool modes (:func:`twin_tool_modes`), a
    real rig's records (``files``, beside the campaign file) are copied in. A record already
    there is kept (a resume does not tap again)."""
    import shutil

    tap = campaign.spec.tap_test
    if tap is None:
        return {}
    out = {}
    for axis in ("x", "y"):
        dest = folder / "tap" / f"tap_{axis}.csv"
        out[axis] = dest
        if dest.exists():
            continue
        dest.parent.mkdir(parents=True, exist_ok=True)
        if campaign.spec.campaign.rig == "real":
            src = campaign.path.parent / tap.files[axis]
            if not src.exists():
                raise ConfigError(f"{campaign.path}: tap_test.files.{axis} = "
                                  f"{tap.files[axis]!r}: file {src} not found")  # fmt: skip
            shutil.copyfile(src, dest)
            continue
        from rig.sim import tap_test_record

        sim = campaign.spec.sim
        tap_test_record(twin_tool_modes(campaign), axis, dest, tap.response, tap.rate_hz,
                        tap.hits, tap.noise, sim.seed + (axis == "y"))  # fmt: skip
    return out


def twin_tool_modes(campaign: Campaign) -> tuple[ToolMode, ...]:
    """The simulated rig's true tool modes in ``campaign``: its ``[[sim.tool_modes]]``, else the
    twin's own structure for the tool (:func:`rig.sim.structure.twin_modes`); never the
    catalogue's modes, which are a measurement of them."""
    from rig.sim.structure import twin_modes

    sim = campaign.spec.sim
    return tuple(sim.tool_modes) if sim.tool_modes is not None else twin_modes(campaign.tool)


def _changed_message(campaign: Campaign, folder: Path, changes: list[str]) -> str:
    return (
        f"{folder}: not resumed: inputs changed since its runs were recorded (a resume would mix "
        "cuts of both in one report):\n  " + "\n  ".join(changes) + "\n  start over with "
        f"`cutlab campaign run {campaign.path} --fresh` (the earlier runs are kept in "
        f"{folder}/before-<time>/), or resume anyway with --force-resume (recorded in "
        f"{folder / 'campaign.json'})"
    )


def _campaign_bar(n: int, show: bool, name: str):  # noqa: ANN202 - a tqdm bar
    from tqdm import tqdm

    # disable=None: no bar when stderr is not a terminal (CI logs); tqdm.write still prints.
    return tqdm(total=n, desc=f"campaign {name}", unit="run", file=sys.stderr, leave=True,
                disable=None if show else True)  # fmt: skip


def _within_run(bar: object, name: str) -> Callable[[int, int], None]:
    last = [-1.0]

    def show(done: int, total: int) -> None:
        now = time.monotonic()
        if now - last[0] < 0.2 and done < total:
            return
        last[0] = now
        bar.set_postfix_str(f"{name[:32]} block {done}/{total}")  # type: ignore[attr-defined]

    return show


# ----------------------------------------------------------------------------------------------
# Dry run
# ----------------------------------------------------------------------------------------------
