"""Step-versus-run agreement of the slider's ``~/step`` (issue 13): a figure, no timing.

For three regimes (the paper's case, a hopping tilted vibration, mu_s > mu on
a slope), a real-time slider (the node's core, on the node's 1 kHz log grid)
is paused at t = 0.1234567 s and stepped: 500 steps of one period, 70 of
seven periods, 300 of an odd 0.0337 s.  Every logged state is compared with
a slider that runs to the same time without a stop, ticking every
millisecond.  Prints max |step - run| / max |run| of x, v and z.

Run: make bench   (or .venv/bin/python bench/step_vs_run.py)
"""

from __future__ import annotations

import numpy as np

from friction_sim.core.model.events import SliderState
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider

REGIMES = {
    "kostek (paper Fig. 2)": (SliderParams(), Inputs()),
    "hopping (beta 30 deg, Pa 20 N)": (SliderParams(mu=0.5, excitation_angle=30.0),
                                       Inputs(excitation_amplitude=20.0, drive_force=0.0)),
    "mu_s = 1.5 mu on a 3 deg slope": (SliderParams(static_ratio=1.5, track_inclination=3.0),
                                       Inputs(excitation_amplitude=7.0)),
}
STEPS = {"1 period x 500": [0.02] * 500, "7 periods x 70": [0.14] * 70, "0.0337 s x 300": [0.0337] * 300}
MS = 1_000_000
PAUSE_NS = 123_456_700


def stepped(params: SliderParams, inputs: Inputs, lengths: list[float]) -> list[SliderState]:
    """The states logged by a slider paused at PAUSE_NS and stepped by ``lengths`` [s]."""
    rt = RealtimeSlider(params, inputs, wall_ns=0, log_rate=1000.0)
    states = list(rt.tick(PAUSE_NS).samples)
    rt.pause(PAUSE_NS)
    wall = PAUSE_NS
    for length in lengths:
        wall += 3 * MS  # wall time passes between the calls
        assert rt.step(length, wall).accepted
        states += rt.tick(wall).samples
    return states


def running(params: SliderParams, inputs: Inputs, end_ns: int) -> list[SliderState]:
    """The states logged by a slider that runs to ``end_ns`` without a stop, a tick a millisecond."""
    rt = RealtimeSlider(params, inputs, wall_ns=0, log_rate=1000.0)
    states: list[SliderState] = []
    for wall in range(MS, end_ns + MS, MS):
        states += rt.tick(min(wall, end_ns)).samples
    return states


def main() -> None:
    print("step versus run: max |step - run| / max |run| over every logged state (1 kHz grid)")
    for name, (params, inputs) in REGIMES.items():
        for label, lengths in STEPS.items():
            steps = stepped(params, inputs, lengths)
            runs = running(params, inputs, round(steps[-1].t * 1e9))
            assert [s.t for s in steps] == [s.t for s in runs]
            figures = []
            for field in ("x", "v", "z"):
                a = np.array([getattr(s, field) for s in steps])
                b = np.array([getattr(s, field) for s in runs])
                scale = np.max(np.abs(b))
                figures.append(f"{field} {np.max(np.abs(a - b)) / scale if scale else 0.0:.1e}")
            print(f"  {name:32s} {label:16s} {len(steps):6d} states to {steps[-1].t:7.3f} s: {', '.join(figures)}")


if __name__ == "__main__":
    main()
