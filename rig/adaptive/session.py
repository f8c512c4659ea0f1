"""The adaptive controller wired into a campaign run: the rig session's DAQ hands every block to
the run's own sink first and then to the controller (in the acquisition thread, as the live
console's tee does), and the session's streamer, once streaming, carries the overrides.

A safety hold of the controller (over-force, signal lost, chatter without a pocket) becomes the
session's fault, named ``adaptive interlock: ...``: the run records it as an interlock and stops
the program (feed hold first, then reset), so a held cut never waits for the watchdog.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeVar, cast

import numpy as np

from analysis.runs import file as rf
from rig.adaptive.controller import AdaptiveController
from rig.daq import SAMPLE_FORMAT_RAW

if TYPE_CHECKING:
    from analysis.stability import Lobes
    from rig.adaptive.campaign_view import (
        AdaptiveCampaign,
        AdaptiveTest,
        LoopSession,
        PassGeometry,
    )
    from rig.adaptive.feedforward import FeedForward
    from rig.adaptive.settings import AdaptiveSettings
    from rig.daq import Calibration, Daq

#: the rig session adaptive_session wraps (returned as it is when the test is not under the loop)
S = TypeVar("S", bound="LoopSession")


class _Tee:
    """The DAQ sink the DAQ gets: the run's sink, then the controller (zeroed on the first
    ``zero_samples`` samples per channel, the rest before the cut, as the run zeroes)."""

    def __init__(self, sink: Any, owner: Any) -> None:  # an AdaptiveSession or a SendLoop
        self.sink, self.o = sink, owner
        self.info: Any = None
        self._rest: list[np.ndarray] = []
        self._rest_n = 0

    def on_start(self, info: Any, t0_s: float) -> None:
        self.sink.on_start(info, t0_s)
        self.info = info
        self.o.ctl.on_start(info, t0_s)

    def on_block(self, first_sample: int, data: np.ndarray) -> None:
        self.sink.on_block(first_sample, data)
        o, info = self.o, self.info
        if o.drop_after_s is not None:  # the twin's signal loss: the controller hears no more
            if o.ctl.t0_s + (first_sample + data.shape[1]) / info.rate_hz > o.drop_after_s:
                return
        if info.sample_format == SAMPLE_FORMAT_RAW:
            volts = rf.raw_to_volts(data.T, info.scaling_coeff)
        else:
            volts = np.array(data.T, dtype=float)
        if o.ctl.force_of is None:
            self._rest.append(volts)
            self._rest_n += len(volts)
            if self._rest_n < o.zero_samples:
                return
            rest = np.concatenate(self._rest)[: o.zero_samples]
            t_mid = o.ctl.t0_s + (first_sample - self._rest_n + len(volts)) / info.rate_hz
            cal = o.cal.zeroed(rest, t_mid + 0.5 * len(rest) / info.rate_hz)
            o.ctl.force_of = cal.force_from_volts
            self._rest = []
            return
        o.ctl.on_block(first_sample, volts.T)

    def on_event(self, event: Any) -> None:
        self.sink.on_event(event)
        self.o.ctl.on_event(event)


class _Daq:
    def __init__(self, daq: Any, owner: AdaptiveSession) -> None:
        self._daq, self._o = daq, owner

    def start(self, sink: Any) -> None:
        self._daq.start(_Tee(sink, self._o))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._daq, name)


class AdaptiveSession:
    """A rig session (simulated or real GRBL) with the controller in its loop.

    ``cal`` the dynamometer's sheet (zeroed here on ``zero_samples`` at rest);
    ``drop_after_s`` (the twin's fault knob) stops handing blocks to the controller after that
    run-clock time: the recording goes on, the controller hears nothing (signal lost)."""

    def __init__(
        self, session: Any, ctl: AdaptiveController, cal: Any, zero_samples: int,
        drop_after_s: float | None = None, drop_relative: bool = False,
        anticipation: str = "feedback only",
    ) -> None:  # fmt: skip
        self._s = session
        self.ctl = ctl
        self.cal = cal
        self.zero_samples = max(2, int(zero_samples))
        self.drop_after_s = drop_after_s
        self._drop_relative = drop_relative  # drop_after_s counts from the program's start
        self.anticipation = anticipation  # which mode runs, for the run file's start note
        # _Daq tees the blocks and forwards every other member to the session's Daq
        self.daq = cast("Daq", _Daq(session.daq, self))
        # the live console (rig.console.live) finds the controller on the session it wraps
        session.adaptive_controller = ctl
        self.clock = session.clock
        ctl.clock = session.clock

    def start(self, program: Any, writer: Any) -> None:
        self.ctl.writer = writer
        t0 = self.clock()  # the program's start: the loss knob counts from here
        if self._drop_relative and self.drop_after_s is not None:
            self.drop_after_s += t0
            self._drop_relative = False
        self._s.start(program, writer)
        streamer = getattr(self._s, "streamer", None)
        if streamer is None or not hasattr(streamer, "override"):
            raise RuntimeError("adaptive: the session's controller has no real-time override")
        self.ctl.attach(streamer)
        s = self.ctl.s
        msg = (f"adaptive: {s.mode}, target {s.target_force_n:g} N, max {s.max_force_n:g} N, "
               f"dead band {s.dead_band_pct:g} %, slew +{s.slew_up_pct}/-{s.slew_down_pct} % per "
               f"rev, air {s.air_force_n:g} N; {self.anticipation}")  # fmt: skip
        writer.event(rf.EV_NOTE, msg, time_s=t0)
        self.ctl.arm()

    def fault(self) -> str | None:
        f = self._s.fault()
        if f is None and self.ctl.hold_reason is not None:
            return f"adaptive interlock: {self.ctl.hold_reason}"
        return f

    def finished(self) -> bool:
        return self._s.finished() or self.ctl.hold_reason is not None

    def stop(self) -> None:
        self._end()
        self._s.stop()

    def close(self) -> None:
        self._end()
        self._s.close()

    def _end(self) -> None:
        """Stop the watchdog; the loop's figures go in the run file once."""
        self.ctl.close()
        w = self.ctl.writer
        if w is not None and not getattr(self, "_summarised", False):
            self._summarised = True
            m = self.ctl.summary()
            p50, p95 = m["latency_p50_ms"], m["latency_p95_ms"]
            lat = "-" if p50 is None else f"{p50:.1f}/{p95:.1f} ms"
            w.event(rf.EV_NOTE, f"adaptive: summary: {m['revolutions']} revolutions judged "
                    f"({m['cutting_revolutions']} cutting), {m['decisions']} decisions, "
                    f"{m['override_bytes']} override bytes, block-to-byte p50/p95 {lat}, CPU "
                    f"{m['cpu_s']:.2f} s")  # fmt: skip

    def __getattr__(self, name: str) -> Any:
        return getattr(self._s, name)


def protocol_of(campaign: AdaptiveCampaign) -> str:
    """The controller's protocol a campaign streams to (the twin's ``[sim] protocol`` first)."""
    sim = campaign.spec.sim.protocol if campaign.spec.campaign.rig == "sim" else None
    return sim or campaign.machine.dialect


def max_force_of(campaign: AdaptiveCampaign) -> float | None:
    """The hard limit: the lowest of the tool's ``max_force_n`` (its catalogue's), ``[adaptive]
    max_force_n`` and ``[suspenders] force_limit_n`` that are given (the config may only lower
    the tool's cap); None when none is."""
    a = campaign.spec.adaptive
    a_max = a.max_force_n if a is not None else None  # callers check [adaptive] is there
    given = [float(v) for v in (getattr(campaign.tool, "max_force_n", None), a_max,
             campaign.spec.suspenders.force_limit_n) if v is not None]  # fmt: skip
    return min(given) if given else None


def target_of(campaign: AdaptiveCampaign, test: AdaptiveTest) -> tuple[float | None, str]:
    """(target N, where it comes from) for ``test``: ``[adaptive] target_force_n``, else the
    reference load of the campaign's feed rule (seed 001: the slot of ``[feed_rule]
    reference_depth_mm`` at ``base_feed_mm_min``, the cut known safe at the base feed) as the
    per-revolution mean |Fxy| the material's end-mill coefficients predict at ``test``'s spindle
    speed (analysis.forces.evenness, the measure the loop holds); (None, why) without either."""
    from analysis.forces.models import ENDMILL

    a = campaign.spec.adaptive
    if a is not None and a.target_force_n is not None:
        return float(a.target_force_n), "[adaptive] target_force_n"
    rule = campaign.spec.feed_rule
    if rule is None:
        return None, "no target_force_n and no [feed_rule] to take the reference load from"
    coef = getattr(campaign.material, "endmill", None)
    if not ENDMILL.describes(campaign.tool) or coef is None:
        return None, (f"the feed rule's reference load needs an end mill and the material's "
                      f"end-mill coefficients ({campaign.tool.kind}, "
                      f"{'no' if coef is None else 'has'} coefficients)")  # fmt: skip
    import numpy as np

    from analysis.forces.evenness import SteadyCut, feed_plane_force_n

    rpm = abs(float(test.spindle_rpm))
    f = feed_plane_force_n(campaign.tool, coef, SteadyCut(rule.reference_depth_mm, 1.0), rpm,
                           np.array([rule.base_feed_mm_min]))  # fmt: skip
    return float(f[0]), (f"the feed rule's reference load: a {rule.reference_depth_mm:g} mm slot "
                         f"at {rule.base_feed_mm_min:g} mm/min, {rpm:g} rpm")  # fmt: skip


def check_adaptive(campaign: AdaptiveCampaign) -> None:
    """Refuse a loop the controller cannot close: ConfigError naming the file and the field."""
    from analysis.errors import ConfigError

    a = campaign.spec.adaptive
    if a is None:
        return
    where = f"{campaign.path}: [adaptive]"
    from rig.adaptive.override import refusal

    why = refusal(campaign.machine, protocol_of(campaign))
    if why is not None:
        raise ConfigError(f'{where}: {why} ([sim] protocol = "grbl" on the twin)')
    mx = max_force_of(campaign)
    if mx is None:
        raise ConfigError(f"{where} max_force_n: missing; give it in N (or the tool's max_force_n, "
                         "or [suspenders] force_limit_n)")  # fmt: skip
    for t in campaign.tests:
        if not under_loop(campaign, t):
            continue
        target, why = target_of(campaign, t)
        if target is None:
            raise ConfigError(f"{where} target_force_n: missing: {why}; give it in N")
        if not target < mx:
            raise ConfigError(f"{where} target_force_n = {target:g} N ({why}): expected below "
                             f"the hard limit {mx:g} N")  # fmt: skip
    known = {m.group for m in campaign.spec.matrix} | {t.group for t in campaign.spec.tests}
    bad = [g for g in a.groups if g not in known]
    if bad:
        raise ConfigError(f"{where} groups: {bad[0]!r} is no group of the matrix (groups: "
                         f"{', '.join(sorted(known))})")  # fmt: skip


def under_loop(campaign: AdaptiveCampaign, test: AdaptiveTest) -> bool:
    a = campaign.spec.adaptive
    return a is not None and (not a.groups or test.group in a.groups)


def settings_of(campaign: AdaptiveCampaign, test: AdaptiveTest) -> AdaptiveSettings:
    from rig.adaptive.settings import AdaptiveSettings

    a = campaign.spec.adaptive
    assert a is not None  # only under [adaptive] (under_loop)
    target, why = target_of(campaign, test)
    cap = max_force_of(campaign)
    if target is None or cap is None:  # check_adaptive refuses both first, naming the file
        raise ValueError(f"adaptive: no target ({why}) or no hard limit")
    return AdaptiveSettings(
        mode=a.mode, target_force_n=target, max_force_n=cap,
        dead_band_pct=a.dead_band_pct, slew_up_pct=a.slew_up_pct, slew_down_pct=a.slew_down_pct,
        settle_revs=a.settle_revs, air_force_n=a.air_force_n, stall_revs=a.stall_revs,
        chatter_revs=a.chatter_revs, min_pct=a.min_pct, max_pct=a.max_pct,
    )  # fmt: skip


#: speeds the lobes are computed at, 1.25 % apart over 50-150 % of the commanded speed (within
#: the override range): 81 speeds of a 2-DOF slot cost 5-10 s of CPU on this busy machine, paid
#: once before the run; further pockets are rarely worth a spindle twice or half as fast
LOBE_SPEEDS = 81
LOBE_SPAN_PCT = (50, 150)


def lobes_for(
    campaign: AdaptiveCampaign, test: AdaptiveTest, min_pct: int, max_pct: int
) -> Lobes | None:
    """The stability lobes of ``test``'s cut across the spindle override range
    (:func:`rig.adaptive.cut.lobe_cut`: the twin's ``[sim] tool_modes`` first, else the tool's
    own; the material's end-mill coefficients); None without them (no pocket to go to)."""
    from analysis.stability import stability_lobes
    from rig.adaptive.cut import lobe_cut

    cut = lobe_cut(campaign, test)
    if isinstance(cut, str):
        return None
    rpm0 = abs(float(test.spindle_rpm))
    lo, hi = max(min_pct, LOBE_SPAN_PCT[0]), min(max_pct, LOBE_SPAN_PCT[1])
    rpm = np.linspace(rpm0 * lo / 100, rpm0 * hi / 100, LOBE_SPEEDS)
    return stability_lobes(cut.case(rpm, f"{campaign.name}-adaptive"), "sd")


def adaptive_session(
    campaign: AdaptiveCampaign, test: AdaptiveTest, session: S, cal: Calibration,
    cut: PassGeometry | None = None,
) -> S | AdaptiveSession:  # fmt: skip
    """The campaign runner's hook: ``session`` with the controller in its loop when ``test``'s
    group is under ``[adaptive]``, else ``session`` itself; ``cut`` the test's generated program
    (its block and path: the feed-forward's stock; None: feedback only)."""
    if not under_loop(campaign, test):
        return session
    check_adaptive(campaign)
    a = campaign.spec.adaptive
    assert a is not None  # under_loop: [adaptive] is there
    rate = campaign.spec.daq.rate_hz or campaign.rig.daq.rate_hz
    ff, anticipation = None, "feedback only: the spindle mode holds no force target"
    if a.mode in ("feed", "both"):
        ff, anticipation = _feed_forward(campaign, test, cut)
    ctl = AdaptiveController(
        settings_of(campaign, test), spindle_rpm=test.spindle_rpm,
        channels=tuple(cal.channel_names), clock=session.clock, depth_mm=test.depth_mm,
        chatter_settings=campaign.spec.chatter.settings(),
        lobes=lobes_for(campaign, test, a.min_pct, a.max_pct) if a.mode != "feed" else None,
        feed_forward=ff,
    )  # fmt: skip
    zero = int(round(campaign.spec.daq.rest_s * rate))
    drop = None
    if a.sim_signal_loss_at_s is not None and campaign.spec.campaign.rig == "sim":
        drop = a.sim_signal_loss_at_s  # made absolute at the program's start
    return AdaptiveSession(session, ctl, cal, zero, drop_after_s=drop, drop_relative=True,
                           anticipation=anticipation)  # fmt: skip


def _feed_forward(
    campaign: AdaptiveCampaign, test: AdaptiveTest, cut: PassGeometry | None
) -> tuple[FeedForward | None, str]:
    """(the loop's anticipation for ``test``, the start note's words for it): the predicted load
    of the pass (:func:`rig.adaptive.predict.campaign_profile`) or why the loop runs on the
    measured force alone."""
    from rig.adaptive.feedforward import FeedForward
    from rig.adaptive.grbl_codes import APPLY_DELAY_S
    from rig.adaptive.predict import campaign_profile

    s = settings_of(campaign, test)
    profile, why = campaign_profile(campaign, test, cut)
    if profile is None:
        return None, f"feedback only: {why}"
    ff = FeedForward(profile, s.target_force_n, s.air_force_n, APPLY_DELAY_S)
    return ff, f"feed-forward: {why}"
