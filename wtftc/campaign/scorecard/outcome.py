"""What became of a run: held, brought down, tripped, failed structurally, or failed.

The rules read a sweep's run row (wtftc.campaign.sweep.tasks, the columns of its
``runs/*.parquet``), in this order; the first that applies decides:

1. ``status == "failed"`` → **failed**: the run raised (wtftc's own error, OpenFAST past
   its time limit, OpenFAST writing no output); ``cause`` holds the exception. Its
   metrics are missing: not a result of the controller's, kept apart from every other.
2. ``status == "diverged"`` and ``cause`` starting with "OpenFAST stopped" (the head of
   :func:`wtftc.openfast.engine.abort_message`, OpenFAST's own reason after it) →
   **failed_structurally** when the reason names a strike (:data:`STRUCTURAL`: AeroDyn's
   ``edInflow:TwrInfl:Tower strike.``, a blade through the tower, as the IEA 15-MW's
   ROSCO under the runaway to fine at 24 m/s, seed 0, in tests/data/openfast_runs),
   else **failed**: OpenFAST stopped for another reason (the DLC 1.2 NREL 5-MW runs of
   ``paper`` end in ``DLL_controller_call: ... the pitch demand of blade 1 (#42) is
   -3.45e+38 ...: not a finite float``: the controller's numbers, not the structure).
3. ``status == "diverged"`` and ``cause`` ending in "the rotor stalled" (the envelope's
   reason, :meth:`wtftc.sim.integrate.Envelope.reason`: ω_r below ``stall_under_rated``
   × rated, 0.2 in layout.json) → **brought_down**. Threshold 0.2 × rated because it is
   where every run already ends as lost, and it lies below every controller's own speed
   range (ROSCO's minimum rotor speed for the NREL 5-MW, VS_MinOMSpd, is 0.28 × rated):
   a rotor there no longer makes power under control, it is stopping. Every runaway to
   feather of the DLC 2.1 runs in tests/data/openfast_runs that did not hold ends so
   (ω_r 0.2533 rad/s against a floor of 0.2534 on the NREL 5-MW, 40 s onset, lost at
   53-67 s): the feathered blade brakes the rotor, as a shutdown would. This rule comes
   before the overspeed's: a stopped rotor is never counted as an overspeed, whatever
   its peak. ``cause`` ending in "the rotor ran away" (above 2 × rated) → **tripped**.
4. Any other ``diverged`` (wtftc's own plant: a non-finite or |state| > 1e8) → **failed**.
5. ``status == "ok"``: a shutdown (:data:`SHUTDOWN` set) or a speed after the onset
   below 0.2 × rated (:data:`MIN_AFTER_ONSET`) → **brought_down**; a peak rotor speed
   over rated above ``trip`` → **tripped**; else **held**. The peak is
   :data:`PEAK_AFTER_ONSET` where the row has it; else ``overspeed_peak_over_rated``,
   taken over the whole scored window from ``transient_s`` (30 s), before the onset too:
   an upper bound of the peak after it, which may call a run tripped whose peak came
   before the fault (:func:`explain` says so). ``paired.held`` is rule 5 with that peak.

The three keys in capitals are not in a sweep's rows yet; the scorecard's runner is to
add them (wtftc.results.metrics). ``onset_s``: the fault's onset (default: the row's
``onset_s``; None for a fault-free run, scored over its whole window).
"""

from __future__ import annotations

import re

from wtftc.artefacts import layout as lay
from wtftc.openfast.engine import abort_message
from wtftc.sim.integrate import Envelope

#: the outcomes, in the order the rules test them
OUTCOMES = ("failed", "failed_structurally", "brought_down", "tripped", "held")
#: the row's keys the rules read that a sweep's rows do not hold yet (module docstring)
PEAK_AFTER_ONSET = "overspeed_peak_over_rated_after_onset"
MIN_AFTER_ONSET = "speed_min_over_rated_after_onset"
SHUTDOWN = "shutdown_at_s"
#: OpenFAST's reasons that are the structure's: a blade striking the tower
STRUCTURAL = re.compile(r"\bstrike\b", re.IGNORECASE)
#: the head of every OpenFAST abort's cause, and the envelope's two endings, taken from
#: the code that writes them
OPENFAST_STOPPED = abort_message("", 1).split(" (", 1)[0]
STALLED = Envelope(0, 1.0, 2.0).reason(0.5).rsplit(": ", 1)[1]
RAN_AWAY = Envelope(0, 1.0, 2.0).reason(3.0).rsplit(": ", 1)[1]
#: the speed over rated below which a rotor has stopped (layout.json's envelope)
STOPPED_BELOW = lay.layout()["envelope"]["stall_under_rated"]


def classify(row: dict, onset_s: float | None = None, trip: float = 1.2) -> str:
    """The run's outcome, one of :data:`OUTCOMES` (module docstring's rules)."""
    return explain(row, onset_s, trip)[0]


def explain(row: dict, onset_s: float | None = None, trip: float = 1.2) -> tuple[str, str]:
    """(outcome, why): :func:`classify`'s outcome and the evidence, in one line."""
    onset = onset_s if onset_s is not None else row.get("onset_s")
    status, cause = row["status"], row.get("cause") or ""
    at = row.get("diverged_at_s")
    when = "" if at is None else f" at {at:g} s" + (
        "" if onset is None else f" ({at - onset:+g} s from the onset)")
    if status == "failed":
        return "failed", f"the run raised: {cause}"
    if status == "diverged":
        if cause.startswith(OPENFAST_STOPPED):
            kind = "failed_structurally" if STRUCTURAL.search(cause) else "failed"
            return kind, cause + when
        if cause.endswith(STALLED):
            return "brought_down", f"stopped{when}: {cause}"
        if cause.endswith(RAN_AWAY):
            return "tripped", f"ran away{when}: {cause}"
        return "failed", f"lost{when}, not by the rotor: {cause}"
    if status != "ok":
        raise ValueError(f"a run's status is ok, diverged or failed, not {status!r}")
    if row.get(SHUTDOWN) is not None:
        return "brought_down", f"shut down at {row[SHUTDOWN]:g} s"
    low = row.get(MIN_AFTER_ONSET)
    if low is not None and low < STOPPED_BELOW:
        return "brought_down", f"slowed to {low:.3g} × rated after the onset"
    return _peak(row, onset, trip)


def _peak(row: dict, onset: float | None, trip: float) -> tuple[str, str]:
    """Tripped or held by the peak speed: after the onset where the row has it."""
    if onset is not None and row.get(PEAK_AFTER_ONSET) is not None:
        peak, where = row[PEAK_AFTER_ONSET], f"after the onset at {onset:g} s"
    else:
        peak = row.get("overspeed_peak_over_rated") or 0.0
        where = f"over the scored window from {row.get('transient_s') or 0.0:g} s" + (
            "" if onset is None else f", the onset at {onset:g} s within it (no peak "
            "after the onset in the row)")
    if peak > trip:
        return "tripped", f"peak {peak:.4g} × rated > {trip:g} {where}"
    return "held", f"peak {peak:.4g} × rated ≤ {trip:g} {where}"
