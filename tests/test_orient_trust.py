"""Warnings on inputs that cannot be trusted (issue 43): a gyroscope or accelerometer held at
its range, a magnetometer whose field strength drifts, a recording without rest; returned by
the orientation API, printed by ``simbench orient``, and silent on clean recordings."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from calibration.orientation import field_drift, longest_rest, saturated_axes
from calibration.orientation.trust import _piled_up
from calibration.rotations import matrix_to_quat, rotvec_to_matrix
from simbench.api import orient
from simbench.cli import main
from simbench.io.imu import ImuRecording, read_broad

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
FIELD_W = 48.0 * np.array([0.0, np.cos(np.deg2rad(66.0)), -np.sin(np.deg2rad(66.0))])
RATE = 100.0


def turning(seed: int, n: int = 3000, rest_s: float = 0.0, rate_rad_s: float = 1.0):
    """A sensor turned every way (rotation vector a smoothed random walk, about ``rate_rad_s``
    RMS), after ``rest_s`` seconds at rest; ideal acc (gravity only, 0.02 m/s^2 noise), gyro
    (0.01 rad/s noise) and field (0.2 uT)."""
    rng = np.random.default_rng(seed)
    w = gaussian_filter1d(rng.normal(size=(n, 3)), 10, axis=0)
    w *= rate_rad_s / np.sqrt(np.mean(np.sum(w**2, axis=1)))
    still = round(rest_s * RATE)
    w[:still] = 0.0
    R = np.empty((n, 3, 3))
    R[0] = np.eye(3)
    step = rotvec_to_matrix(w / RATE)
    for i in range(1, n):
        R[i] = R[i - 1] @ step[i]
    acc = np.einsum("fji,j->fi", R, [0.0, 0.0, 9.81]) + rng.normal(scale=0.02, size=(n, 3))
    mag = np.einsum("fji,j->fi", R, FIELD_W) + rng.normal(scale=0.2, size=(n, 3))
    gyro = w + rng.normal(scale=0.01, size=(n, 3))
    return acc, gyro, mag, R


def recording(acc, gyro, mag, R) -> ImuRecording:
    n = acc.shape[0]
    return ImuRecording(
        names=("imu",),
        time_s=np.arange(n) / RATE,
        acc=acc[:, None],
        gyro=gyro[:, None],
        mag=mag[:, None],
        valid=np.ones((n, 1), dtype=bool),
        q_true=matrix_to_quat(R)[:, None],
        evaluate=None,
        rate_hz=RATE,
        source="test",
    )


def test_a_clipped_gyroscope_and_accelerometer_are_found():
    """A gyroscope clipping at its range on about 17 % of the samples (issue 43's example: VQF
    given such a gyroscope said nothing) and an accelerometer at its range on one axis: each is
    named; the same readings unclipped are not."""
    acc, gyro, mag, R = turning(1, rest_s=3.0, rate_rad_s=4.0)
    top = np.quantile(np.abs(gyro), 0.94)  # about 17 % of the samples beyond it on some axis
    clipped = np.clip(gyro, -top, top)
    found = saturated_axes(clipped)
    assert {s.axis for s in found} == {0, 1, 2}
    assert all(s.value == pytest.approx(top) and s.fraction > 0.01 for s in found)
    assert saturated_axes(gyro) == []
    assert saturated_axes(np.zeros((500, 3))) == []  # no reading is not a clipped one
    a = acc.copy()
    a[:, 2] = np.clip(a[:, 2], -8.0, 8.0)  # a range below gravity on z
    rec = recording(a, clipped, mag, R)
    warnings = orient(rec, "triad").warnings
    assert sum("gyroscope axis" in w and "saturated" in w for w in warnings) == 3
    assert sum("accelerometer axis z held at +-8" in w for w in warnings) == 1
    assert orient(recording(acc, gyro, mag, R), "triad").warnings == ()


def test_a_gyroscope_clipping_to_a_noisy_value_is_found_a_smooth_extreme_is_not():
    """A gyroscope that clips to its range plus a little noise (RepoIMU's Xsens: 7.36-7.37 rad/s)
    repeats no value, yet its samples pile up at the top; smooth extremes do not, however many and
    however coarsely quantised (a swing at a constant amplitude, a still sensor)."""
    rng = np.random.default_rng(7)
    _, gyro, _, _ = turning(4, rate_rad_s=4.0)
    top = np.quantile(np.abs(gyro[:, 0]), 0.95)
    clipped = gyro.copy()
    over = np.abs(clipped[:, 0]) > top
    clipped[over, 0] = np.sign(clipped[over, 0]) * (top - rng.uniform(0.0, 4e-4 * top, over.sum()))
    assert np.unique(np.abs(clipped[:, 0])).size > 0.99 * clipped.shape[0]  # no value repeats
    (found,) = saturated_axes(clipped)
    assert found.axis == 0 and found.value == pytest.approx(top, rel=1e-3) and found.fraction > 0.04
    t = np.arange(6000) / RATE
    swing = np.stack([np.sin(2 * np.pi * 0.7 * t), np.cos(2 * np.pi * 0.3 * t), np.sin(t)], axis=1) * 3.0
    x = swing + rng.normal(scale=0.005, size=swing.shape)
    assert saturated_axes(x) == []
    still = 0.3 + rng.normal(scale=0.01, size=(6000, 3))
    # the pile-up test on quantised readings (the repeated value flags them); a still axis whose
    # noise spans a few levels only is not a smooth extreme, and is left out
    for lsb, y in ((1e-3, x), (2e-2, x), (1e-3, still)):
        q = np.round(y / lsb) * lsb
        a = np.abs(q)
        assert [_piled_up(q[:, j], a[:, j], float(a[:, j].max())) for j in range(3)] == [0, 0, 0]


def test_a_field_strength_that_drifts_is_found():
    """A magnetometer whose gain drifts by 10 % over the recording (temperature) is named; a
    steady one, or one with a magnet attached for a tenth of the recording, is not."""
    acc, gyro, mag, R = turning(2, rest_s=3.0)
    t = np.arange(acc.shape[0]) / RATE
    drifting = mag * (1.0 + 0.1 * t / t[-1])[:, None]
    change, spread = field_drift(drifting, t)
    assert change == pytest.approx(4.8, rel=0.1) and change > 3 * spread
    warnings = orient(recording(acc, gyro, drifting, R), "triad").warnings
    assert len(warnings) == 1 and "field strength drifts by +4." in warnings[0]
    steady_change, steady_spread = field_drift(mag, t)
    assert abs(steady_change) < 3 * steady_spread
    magnet = mag.copy()
    magnet[1000:1300] += 20.0
    assert orient(recording(acc, gyro, magnet, R), "triad").warnings == ()


def test_a_recording_without_rest_is_named_for_the_built_in_methods():
    """Turning all the time: no rest of 1.5 s (VQF's rest detection); the warning names the
    gyroscope's bias for a gyro-aided method. With 3 s of rest first, none."""
    acc, gyro, mag, R = turning(3)
    assert longest_rest(acc, gyro, RATE) < 1.5
    rec = recording(acc, gyro, mag, R)
    (warning,) = orient(rec, "triad").warnings
    assert "no rest of 1.5 s" in warning and "bias" not in warning
    (warning,) = orient(rec, "mahony").warnings
    assert "gyroscope's bias is not estimated at rest" in warning
    acc, gyro, mag, R = turning(3, rest_s=3.0)
    assert 2.5 <= longest_rest(acc, gyro, RATE) <= 3.0  # the 3 s, less up to the 0.5 s low-pass
    assert orient(recording(acc, gyro, mag, R), "mahony").warnings == ()


def test_the_command_prints_the_warnings(tmp_path, capsys):
    """``simbench orient`` on a BROAD-format file whose gyroscope clips."""
    acc, gyro, mag, _ = turning(4, rest_s=3.0, rate_rad_s=4.0)
    top = np.quantile(np.abs(gyro), 0.94)
    path = tmp_path / "clipped.hdf5"
    with h5py.File(path, "w") as fh:
        fh["imu_acc"], fh["imu_gyr"], fh["imu_mag"] = acc, np.clip(gyro, -top, top), mag
        fh.attrs["sampling_rate"] = RATE
    assert main(["orient", str(path), "--method", "triad"]) == 0
    out = capsys.readouterr().out
    assert out.count("warning: imu: gyroscope axis") == 3


@pytest.mark.skipif(
    not SHARED_DATA.is_dir(), reason="../shared/data (BROAD trials) not beside the repository"
)
@pytest.mark.parametrize(
    "name", ["broad_02_undisturbed_slow_rotation_B.hdf5", "broad_30_disturbed_stationary_magnet_C.hdf5"]
)
def test_no_warning_on_clean_broad_trials(name):
    """BROAD's trials are clean inputs (all 22 measured: none warns): nothing held at its range,
    no drift, rests between the motions."""
    from simbench.orient import input_warnings

    rec = read_broad(SHARED_DATA / name)
    assert input_warnings(rec, builtin=True, gyro_aided=True) == ()
