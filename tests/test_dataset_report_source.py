"""``simbench report`` of a dataset with markers calibrates the markers, scores joint centres against
the truth in the world, and names its session (issue 44)."""

from __future__ import annotations

import json

import pytest

from simbench.cli import main
from simbench.io.dataset import read_dataset
from simbench.report.dataset import dataset_report
from simbench.report.plots import residual_histograms_figure


@pytest.fixture(scope="module")
def with_markers(tmp_path_factory):
    """Ideal sensors and exact markers (no skin motion, no camera noise): every joint centre is
    exact from either source."""
    path = tmp_path_factory.mktemp("source") / "m.h5"
    assert main(["simulate", "--duration", "4", "--markers", "-o", str(path)]) == 0
    return path


def _results(path, tmp_path, **kwargs) -> dict:
    out = tmp_path / kwargs.get("source", "auto")
    dataset_report(path, out, **kwargs)
    return json.loads((out / "results.json").read_text())


def test_markers_are_calibrated_when_the_dataset_has_them_and_scored_in_the_world(with_markers, tmp_path):
    auto = _results(with_markers, tmp_path)
    poses = _results(with_markers, tmp_path, source="poses")
    assert auto["poses"] == "marker clusters" and poses["poses"] == "sensor poses"
    ds = read_dataset(with_markers)
    names = {f"{p}-{c}" for p, c in zip(ds.truth.parent, ds.truth.child, strict=True)}
    for results in (auto, poses):
        errors = results["joint_centre_error_mm"]
        assert set(errors) == names
        assert max(errors.values()) < 0.01, errors  # exact data: exact centres, either frame
        assert results["hierarchy_correct"]
    # lengths are distances within a segment: the same in a cluster's frame as in a sensor's
    for a, b in zip(auto["lengths_cm"], poses["lengths_cm"], strict=True):
        assert a["computed"] == pytest.approx(b["computed"], abs=1e-3) and a["length"] == b["length"]


def test_the_source_is_checked_and_the_histograms_name_their_session(with_markers, tmp_path, capsys):
    plain = tmp_path / "plain.h5"
    assert main(["simulate", "--duration", "2", "-o", str(plain)]) == 0
    assert main(["report", str(plain), "--source", "markers", "--out", str(tmp_path / "r")]) == 2
    assert "--source markers, but the dataset has no markers" in capsys.readouterr().err
    assert main(["report", str(plain), "--out", str(tmp_path / "r")]) == 0  # auto: the sensors' poses
    fig = residual_histograms_figure([], 1.0, session="m.h5, marker clusters")
    assert fig._suptitle.get_text() == "joint residuals: m.h5, marker clusters"
