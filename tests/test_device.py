"""The SBI step on a device (dynamics/device.py): the engine against the host stepper.

On every machine the engine runs with the "numpy" backend, which uses the host's kernels and
must reproduce a host run bit for bit: any difference is a bookkeeping error of the engine (field
sync, frame shifts, Δt cache, loading upload). Where CuPy and a GPU are present, the CUDA
kernels are compared with the host too (rounding differences only).
"""
import numpy as np
import pytest

from slippulse.core.params import ParameterError
from slippulse.dynamics.device import DeviceStepper, cupy_unavailable
from slippulse.dynamics.stepper import KostrovInterface, PredictorCorrector, TimeStepRule
from slippulse.timedomain.seeding import DomainSpec
from slippulse.timedomain.verify import VerifySettings, verify_pulse


def _run(pulse, params, device, distance=0.1, perturbation=("excess", 1e-3)):
    return verify_pulse(pulse, params, distance, DomainSpec(dx=1e-2, ahead=2.0, behind=2.0),
                        VerifySettings(n_samples=6, n_snapshots=2, track_every=2,
                                       perturbation=perturbation, device=device),
                        progress=False)


def test_numpy_engine_reproduces_the_host_run_bit_for_bit(pulse12, params):
    """A perturbed 1.2 τ_min pulse, frame shifts and the far-field load moving with it: the
    engine's run equals the host's exactly (same operations, same order)."""
    pulse = pulse12.to_pulse()
    host = _run(pulse, params, "cpu")
    dev = _run(pulse, params, "numpy")
    assert host.info["status"] == dev.info["status"] == "finished"
    assert host.info["shift_cells"] > 5          # the frame moved: roll_frame was exercised
    assert dev.info["n_steps"] == host.info["n_steps"]
    for key, val in host.series.items():
        np.testing.assert_array_equal(dev.series[key], val, err_msg=key)
    np.testing.assert_array_equal(dev.snapshots[-1][2], host.snapshots[-1][2])


def test_engine_fields_read_only_until_assigned(pulse12, params):
    """A field read from the device is a read-only copy (an in-place write would be lost); an
    assigned field is the host's until the next step uploads it."""
    from slippulse.timedomain.seeding import seed_pulse

    seed = seed_pulse(pulse12.to_pulse(), params, DomainSpec(dx=1e-2, ahead=2.0, behind=2.0))
    st = DeviceStepper.from_host(seed.stepper, "numpy")
    st.step()
    with pytest.raises(ValueError):
        st.V[0] = 1.0
    v = np.array(st.V)
    v[:3] = 7.0
    st.V = v
    st.V[3] = 7.0                                # writeable until the next step
    assert st.V[3] == 7.0 and st.v_max() == 7.0
    st.step()
    assert not st.V.flags.writeable


def test_engine_refuses_what_it_does_not_model(params):
    law = KostrovInterface(params, v_r=1000.0, dtau=1e6, x0=0.0)
    host = PredictorCorrector(params, 64, 1.0, law, rule=TimeStepRule())
    with pytest.raises(ParameterError, match="rate-and-state"):
        DeviceStepper.from_host(host, "numpy")


@pytest.mark.skipif(cupy_unavailable() is None, reason="CuPy and a GPU are present")
def test_cupy_without_a_gpu_is_a_one_line_error(pulse12, params):
    with pytest.raises(ParameterError, match="device='cupy' cannot run here"):
        _run(pulse12.to_pulse(), params, "cupy", distance=0.001)


@pytest.mark.skipif(cupy_unavailable() is not None, reason=str(cupy_unavailable()))
def test_cupy_kernels_agree_with_the_host(pulse12, params):
    """CUDA friction solve, state update, SOE sums and cuFFT against the host: the same run to
    rounding (measured on an H100: see docs/dynamic.md §5)."""
    pulse = pulse12.to_pulse()
    host = _run(pulse, params, "cpu")
    dev = _run(pulse, params, "cupy")
    assert dev.info["n_steps"] == host.info["n_steps"]
    for key in ("v_max", "L", "c_p"):
        np.testing.assert_allclose(dev.series[key], host.series[key], rtol=1e-9, err_msg=key)
    np.testing.assert_allclose(dev.snapshots[-1][2], host.snapshots[-1][2], rtol=1e-8,
                               atol=1e-12 * pulse.v_max)


@pytest.mark.skipif(cupy_unavailable() is None, reason="CuPy and a GPU are present")
def test_cli_device_cupy_without_a_gpu_says_why_and_writes_nothing(tmp_path, steady12_with_spectrum,
                                                                   capsys):
    import os

    from slippulse.cli.app import main
    out = str(tmp_path / "v.h5")
    code = main(["dynamic", "verify", "--steady", steady12_with_spectrum, "--distance", "0.01",
                 "--dx", "8e-3", "--samples", "4", "--out", out, "--no-progress",
                 "--device", "cupy"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "device='cupy' cannot run here" in err[0], err
    assert not os.path.exists(out)
