"""C3D through ezc3d (issue 12, item 5): units, invalid samples, ANALOG without channels, truncation."""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np
import pytest
from numpy.testing import assert_allclose

from simbench.cli import main
from simbench.errors import InputError
from simbench.io.c3d import c3d_poses, read_c3d, read_c3d_markers, write_c3d_markers
from simbench.sim.markers import simulate_marker_chain

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def write_raw(path: Path, xyz: np.ndarray, units: str, residual: np.ndarray) -> None:
    """A C3D file written by ezc3d directly: ``xyz`` (F, M, 3) in ``units``, residuals (F, M)."""
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [200.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = [f"M{k}" for k in range(xyz.shape[1])]
    c["parameters"]["POINT"]["UNITS"]["value"] = [units]
    points = np.ones((4, xyz.shape[1], xyz.shape[0]))
    points[:3] = np.transpose(xyz, (2, 1, 0))
    c["data"]["points"] = points
    c["data"]["meta_points"]["residuals"] = residual.T[None]
    c.write(str(path))


@pytest.mark.parametrize(("units", "per_m"), [("mm", 1000.0), ("cm", 100.0), ("m", 1.0)])
def test_units_rate_and_invalid_samples(tmp_path, units, per_m):
    rng = np.random.default_rng(5)
    xyz_m = rng.uniform(-1.0, 1.0, (30, 4, 3))
    residual = np.zeros((30, 4))
    residual[3, 2] = -1.0  # C3D's invalid mark
    path = tmp_path / f"{units}.c3d"
    write_raw(path, xyz_m * per_m, units, residual)
    labels, back, rate = read_c3d_markers(path)
    assert labels == ["M0", "M1", "M2", "M3"] and rate == 200.0
    assert np.isnan(back[3, 2]).all() and np.isfinite(np.delete(back.reshape(-1, 3), 3 * 4 + 2, 0)).all()
    ok = np.isfinite(back)
    # float32 storage: relative precision 6e-8 of values up to 1000
    assert_allclose(back[ok], xyz_m[ok], atol=1e-6)


def test_round_trip_with_analog_parameters_and_no_analog_channels(tmp_path):
    rng = np.random.default_rng(6)
    xyz = rng.normal(0.0, 0.5, (50, 3, 3))
    xyz[7, 1] = np.nan
    path = tmp_path / "w.c3d"
    write_c3d_markers(path, ["A", "B", "C"], xyz, 120.0)
    c = ezc3d.c3d(str(path))
    assert "ANALOG" in c["parameters"] and int(c["parameters"]["ANALOG"]["USED"]["value"][0]) == 0
    labels, back, rate = read_c3d_markers(path)
    assert labels == ["A", "B", "C"] and rate == 120.0 and back.shape == xyz.shape
    assert np.array_equal(np.isnan(back), np.isnan(xyz))
    assert_allclose(back[np.isfinite(back)], xyz[np.isfinite(xyz)], atol=1e-6)  # float32 mm


def test_truncated_and_damaged_files_are_errors_naming_the_file(tmp_path):
    path = tmp_path / "w.c3d"
    write_c3d_markers(path, ["A", "B", "C"], np.zeros((400, 3, 3)), 100.0)
    data = path.read_bytes()
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"cut\.c3d: truncated C3D file: the header announces 400 frames"):
        read_c3d_markers(cut)
    tiny = tmp_path / "tiny.c3d"
    tiny.write_bytes(data[:100])
    with pytest.raises(InputError, match=r"tiny\.c3d: not a C3D file"):
        read_c3d_markers(tiny)
    with pytest.raises(InputError, match=r"nothere\.c3d: no such file"):
        read_c3d_markers(tmp_path / "nothere.c3d")


@pytest.mark.skipif(not SHARED_DATA.is_dir(), reason="../shared/data not beside the repository")
def test_real_file_reads_and_its_half_is_rejected(tmp_path):
    real = SHARED_DATA / "biobuddy_right_hip.c3d"
    labels, xyz, rate = read_c3d_markers(real)
    assert xyz.shape == (1690, 73, 3) and rate == 100.0 and "RASIS" in labels
    assert 0.5 < np.nanmedian(np.abs(xyz[..., 2])) < 2.0  # heights in metres, not millimetres
    half = tmp_path / "half.c3d"
    data = real.read_bytes()
    half.write_bytes(data[: len(data) // 2])  # ezc3d alone reads this as a shorter recording
    with pytest.raises(InputError, match=r"half\.c3d: truncated C3D file: the header announces 1690 frames"):
        read_c3d_markers(half)


def test_exact_zero_points_are_missing_with_a_note(tmp_path):
    """Many exporters write a gap as (0, 0, 0) with a valid residual: read as missing, counted.

    A zero in one or two coordinates is a position like any other; a negative residual stays
    missing whatever the coordinates.
    """
    rng = np.random.default_rng(7)
    xyz_mm = rng.uniform(-1000.0, 1000.0, (40, 5, 3))
    xyz_mm[10:14] = 0.0  # every marker, four frames
    xyz_mm[20, 1] = 0.0
    xyz_mm[21, 2, :2] = 0.0  # (0, 0, z): seen
    residual = np.zeros((40, 5))
    residual[30, 3] = -1.0
    path = tmp_path / "zeros.c3d"
    write_raw(path, xyz_mm, "mm", residual)
    read = read_c3d(path)
    missing = np.zeros((40, 5), dtype=bool)
    missing[10:14] = missing[20, 1] = missing[30, 3] = True
    assert np.array_equal(np.isnan(read.xyz_m).any(axis=2), missing)
    assert np.isnan(read.xyz_m[missing]).all()
    assert_allclose(read.xyz_m[21, 2], xyz_mm[21, 2] / 1000.0, atol=1e-6)
    assert read.units == "mm" and len(read.notes) == 1
    assert "21 sample(s) of 5 marker(s) in 5 frame(s) at exactly (0, 0, 0) read as missing" in read.notes[0]


def test_zero_burst_leaves_the_clusters_and_is_noted(tmp_path):
    x, truth, _ = simulate_marker_chain(np.random.default_rng(101))
    x[100:110] = 0.0  # every marker, as an exporter writes a gap
    path = tmp_path / "burst.c3d"
    write_raw(path, x * 1000.0, "mm", np.zeros(x.shape[:2]))
    rec = c3d_poses(path)
    assert len(rec.names) == len(truth) + 1  # the moving clusters and the still group
    assert not rec.valid[100:110].any() and rec.valid[:100].all() and rec.valid[110:].all()
    assert any("at exactly (0, 0, 0) read as missing" in n for n in rec.notes)
    everywhere = tmp_path / "zero.c3d"
    write_raw(everywhere, np.zeros((20, 4, 3)), "mm", np.zeros((20, 4)))
    with pytest.raises(InputError, match=r"zero\.c3d: no marker seen in any of its 20 frame\(s\)"):
        c3d_poses(everywhere)


def test_units_given_override_the_files_with_a_note(tmp_path, capsys):
    """A file in mm labelled m: --units mm reads it in mm (and says so); without it the file's
    label is used and the warning says what --units would change."""
    x, _, _ = simulate_marker_chain(np.random.default_rng(102))
    path = tmp_path / "mislabelled.c3d"
    write_raw(path, x * 1000.0, "m", np.zeros(x.shape[:2]))
    as_labelled = read_c3d(path)
    assert as_labelled.units == "m" and as_labelled.notes == ()
    assert_allclose(as_labelled.xyz_m, x * 1000.0, rtol=1e-6)
    asked = read_c3d(path, units="mm")
    assert asked.units == "mm"
    assert asked.notes == ("positions read in mm as asked (--units), not in the file's POINT:UNITS 'm'",)
    assert_allclose(asked.xyz_m, x, atol=1e-6)
    assert read_c3d(path, units="m").notes == ()  # the file's own unit: nothing to note
    with pytest.raises(InputError, match="units to be one of"):
        read_c3d(path, units="furlong")
    assert main(["calibrate", str(path), "--units", "mm", "--no-slip"]) == 0
    out = capsys.readouterr().out
    assert "positions read in mm as asked (--units)" in out and "limb length(s) outside" not in out
    assert main(["calibrate", str(path), "--no-slip"]) == 0
    out = capsys.readouterr().out
    assert "are the positions really in the file's POINT:UNITS? (--units overrides it)" in out
