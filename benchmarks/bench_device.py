"""Seconds per SBI step: the host stepper and the device engine side by side, on one seeded pulse
(docs/dynamic.md §11). What a session with a GPU should measure first, in one short call:

    python benchmarks/bench_device.py FAMILY.h5 LABEL --dx 0.004 --ahead 48 --behind 48 \\
        --steps 300 [--devices cpu cupy] [--concurrent 1 2 4]

For each device the pulse is seeded (as ``slippulse dynamic verify`` does, with the front-frame
eigenmode when the file holds the spectrum), stepped ``--steps`` times through the verify driver's
own per-step work (the step, max V, the front measurement and frame shift every 4 steps), and the
steady-state time per step is printed (the first 20 steps, compiles and Δt coefficients, are not
counted). ``--concurrent K`` runs K such processes at once on the device (a scan's ``--workers``)
and prints the time per step of each. ``cpu`` is one host thread. ``numpy`` (the engine on the
host) measures the engine's bookkeeping. Print the machine's load with the figures.
"""
import argparse
import multiprocessing as mp
import os
import sys
import time

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src")
sys.path.insert(0, HERE)


def one(path, label, dx, ahead, behind, steps, device, out=None):
    import math

    from slippulse.core.h5io import read_pulse
    from slippulse.dynamics.stepper import TimeStepRule
    from slippulse.timedomain.perturbation import HISTORIES
    from slippulse.timedomain.seeding import DomainSpec, follow_pulse, seed_pulse
    from slippulse.timedomain.verify import front_position

    pulse, params = read_pulse(path, label)
    seed = seed_pulse(pulse, params, DomainSpec(dx=dx, ahead=ahead, behind=behind),
                      rule=TimeStepRule(kind="adaptive"), history_options=HISTORIES["cheap"])
    try:
        from slippulse.timedomain.eigenmode import leading_mode, perturb_along_mode
        perturb_along_mode(seed, leading_mode(pulse, params, path=path), 3e-3, frame="front")
    except Exception as exc:                    # noqa: BLE001 - no spectrum: the steady pulse
        print(f"  ({label}: unperturbed: {exc})", file=sys.stderr)
    if device != "cpu":
        from slippulse.dynamics.device import DeviceStepper
        seed.stepper = DeviceStepper.from_host(seed.stepper, device)
    st = seed.stepper
    window = (math.ceil(3.0 * pulse.L / st.dx), math.ceil(1.0 * pulse.L / st.dx))
    t0 = None
    for i in range(steps):
        if i == 20:
            st.v_max()                          # let the device finish the warm-up
            t0 = time.perf_counter()
        st.step()
        if st.nstep % 4 == 0:
            xr, _, _ = front_position(*st.peak_window(*window), params.v_star)
            follow_pulse(seed, xr)
        st.v_max()
    per = (time.perf_counter() - t0) / (steps - 20)
    res = (device, st.n, per)
    if out is not None:
        out.put(res)
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("label")
    ap.add_argument("--dx", type=float, default=0.004)
    ap.add_argument("--ahead", type=float, default=48.0)
    ap.add_argument("--behind", type=float, default=48.0)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--devices", nargs="+", default=["cpu", "cupy"])
    ap.add_argument("--concurrent", type=int, nargs="+", default=[1])
    a = ap.parse_args()
    if a.steps <= 20:
        ap.error("--steps must be > 20")
    print(f"load before: {os.getloadavg()}")
    for dev in a.devices:
        for k in a.concurrent if dev != "cpu" else [1]:
            ctx = mp.get_context("spawn")
            q = ctx.Queue()
            procs = [ctx.Process(target=one, args=(a.family, a.label, a.dx, a.ahead, a.behind,
                                                   a.steps, dev, q)) for _ in range(k)]
            for p in procs:
                p.start()
            res = [q.get() for _ in procs]
            for p in procs:
                p.join()
            n = res[0][1]
            per = [r[2] for r in res]
            print(f"{dev:5s} x{k}: N = {n}: {1e3 * max(per):.3f} ms per step (slowest of {k}), "
                  f"{1e9 * max(per) / n:.2f} ns per point-step; per process "
                  + ", ".join(f"{1e3 * p:.3f}" for p in per) + " ms")
    print(f"load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
