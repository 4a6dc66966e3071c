"""What a hierarchical ensemble's report states (issue 25, Fig 5.19's "limits wider by an
amount the report states"): the run drapes its fixed-parameter twin (the same study with
the drawn sd and lengths removed, the same realisations) into ``<run>/fixed``, and the
report states the widening measured between the two ensembles."""

from __future__ import annotations

import html
import json
import re
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import assert_one_line_error, write_study
from uqdrape.cli import main
from uqdrape.ensemble import open_ensemble, read_manifest, sampled_inputs
from uqdrape.ensemble.inputs import realization_sd_deg
from uqdrape.study import load_study
from uqdrape.workflow import preflight, run_report, run_study
from uqdrape.workflow.twin import BAND_WIDER, MEASURED, MOVING, SD_WIDER, SHARE, fixed_twin

#: A small energy drape (13 x 13 nodes), zero-angle sd 1 deg, realisations in chunks of 16.
SMALL = dict(study={"realizations": 32, "chunk_size": 16}, fabric={"material": "ebxhd936_like"},
             process={"blankholder_force_N": 150.0, "friction": 0.2}, solver={"mode": "energy", "rings": 6})
IID = {"mean_deg": 0.0, "sd_deg": 1.0, "correlation": "iid"}
LENGTHS = {"mean_deg": 0.0, "sd_deg": 1.0, "correlation": "exponential", "length_mm": [10.0, 20.0]}
#: A measured row as printed: the median in its value, the 5-95 % over the nodes in its how.
MEDIAN = re.compile(r"(-?[\d.]+) %")
SPREAD = re.compile(r"median over the nodes \(5-95 %: (-?[\d.]+) to (-?[\d.]+) %\) of .*")


def _run(tmp_path, name, zero, report=None, study=None, process=None):
    sections = dict(SMALL, study={**SMALL["study"], **(study or {})}, uncertainty={"zero_angle": zero},
                    process={**SMALL["process"], **(process or {})})
    path = write_study(tmp_path, name, **sections, **({"report": report} if report else {}))
    return path, run_study(path, scheduler="synchronous", progress=False)


def _said(out) -> dict:
    """The report's hierarchical rows: {row: {"value", "how"}}."""
    return json.loads((Path(run_report(out)).parent / "summary.json").read_text(encoding="utf-8"))["extra"]


def _percents(text) -> np.ndarray:
    """(low, median, high) in % from a stated row."""
    mid, (low, high) = float(MEDIAN.fullmatch(text["value"]).group(1)), map(float, SPREAD.fullmatch(text["how"]).groups())
    return np.array([low, mid, high])


def _expected(out) -> dict:
    """The widening from the two ensembles' shears, computed here with numpy: per node the
    sd (ddof 1) and the 5-95 % band (numpy's linear quantiles), over the nodes whose twin
    sd is above MOVING of its largest."""
    with open_ensemble(out) as h, open_ensemble(Path(out) / "fixed") as f:
        assert np.array_equal(h["realization"].values, f["realization"].values)
        hier, fixed = (ds["shear"].transpose("realization", "blankholder_force", ...).values
                       .reshape(ds.sizes["realization"], ds.sizes["blankholder_force"], -1) for ds in (h, f))
    sd_h, sd_f = np.nanstd(hier, axis=0, ddof=1), np.nanstd(fixed, axis=0, ddof=1)  # (levels, nodes)
    band_h, band_f = (np.diff(np.nanquantile(x, [0.05, 0.95], axis=0), axis=0)[0] for x in (hier, fixed))
    moving = sd_f > MOVING * np.nanmax(sd_f, axis=1, keepdims=True)  # of the largest at its level
    spread = [0.05, 0.5, 0.95]
    ratio = sd_h[moving] / sd_f[moving]
    return {"nodes": int(moving.sum()), "sd": 100 * (np.quantile(ratio, spread) - 1),
            "band": 100 * (np.quantile(band_h[moving] / band_f[moving], spread) - 1),
            "share": 100 * np.quantile(1 - ratio ** -2, spread)}


@pytest.mark.parametrize("zero, forces", [(dict(IID, sd_dof=6.0), 150.0), (dict(LENGTHS, length_log_sd=0.5), 150.0),
                                          (dict(IID, sd_dof=6.0), [0.0, 300.0])], ids=["sd", "lengths", "sweep"])
def test_the_stated_widening_is_the_two_ensembles(tmp_path, zero, forces):
    """A drawn sd (sd_dof 6) or drawn lengths (length_log_sd 0.5), at one force or two: the
    run drapes its twin with the same realisations, and each stated number is the two
    ensembles' own to the printed precision (0.1 %), the levels' nodes pooled; the drawn sd
    widens the limits (median sd and band wider)."""
    _, out = _run(tmp_path, "hier", zero, process={"blankholder_force_N": forces})
    said, expected = _said(out), _expected(out)
    levels = "" if forces == 150.0 else " x levels (of 2 force levels)"
    assert said[MEASURED]["value"] == f"32 realisations, {expected['nodes']:,} nodes{levels}"
    assert said[MEASURED]["how"].startswith("its twin in fixed/: the same realisations with sd and lengths at")
    assert expected["nodes"] > 150 * (1 if forces == 150.0 else 2)  # of 169 a level: the pole is fixed
    for row, key in ((SD_WIDER, "sd"), (BAND_WIDER, "band"), (SHARE, "share")):
        np.testing.assert_allclose(_percents(said[row]), expected[key], rtol=0, atol=0.05 + 1e-9, err_msg=row)
    page = (out / "report" / "index.html").read_text(encoding="utf-8")
    row = said[SD_WIDER]
    assert f"<td class=\"num\">{html.escape(row['value'])}</td><td>{html.escape(row['how'])}</td>" in page
    if "sd_dof" in zero:
        assert expected["sd"][1] > 10 and expected["band"][1] > 5 and expected["share"][1] > 15


def test_the_twin_differs_only_by_the_drawn_sd(tmp_path):
    """The twin's zero-energy angles are the hierarchical run's with each realisation's
    drawn sd replaced by the estimate: the same noise, the sd's normal last in each stream."""
    path = write_study(tmp_path, "hier", **SMALL, uncertainty={"zero_angle": dict(IID, mean_deg=-2.0, sd_dof=6.0)})
    study = load_study(path)
    twin = fixed_twin(study, 32, study.output_dir)
    r = np.arange(32)
    hier, fixed = sampled_inputs(study, r)["gamma0"] + 2.0, sampled_inputs(twin, r)["gamma0"] + 2.0
    np.testing.assert_allclose(hier / realization_sd_deg(study, r)[:, None, None], fixed / 1.0, rtol=1e-12)
    assert twin.uncertainty.fields["zero_angle"].sd_dof is None and twin.output_dir == study.output_dir / "fixed"
    assert not np.allclose(hier, fixed)


def test_the_command_says_the_twin_is_draped_and_a_resume_keeps_both(tmp_path, capsys):
    path = write_study(tmp_path, "hier", **SMALL, uncertainty={"zero_angle": dict(IID, sd_dof=6.0)})
    assert main(["validate", str(path)]) == 0
    said = capsys.readouterr().out
    assert "(mean_deg 0, sd_deg 1; iid, sd_dof 6)" in said and "its fixed-parameter twin in fixed/ (twice" in said
    assert main(["run", str(path), "--scheduler", "synchronous", "--no-report"]) == 0
    captured = capsys.readouterr()
    assert "hier: draping its fixed-parameter twin into " in captured.err
    assert "the same 32 realisations" in captured.err and "[report] fixed_twin = false skips it" in captured.err
    assert captured.out.splitlines()[1] == f"fixed-parameter twin: ensemble written to {tmp_path / 'hier' / 'fixed'}: " \
                                           "2 chunks drawn"
    assert main(["run", str(path), "--scheduler", "synchronous", "--no-report", "-q"]) == 0
    assert capsys.readouterr().out.splitlines()[1].startswith("fixed-parameter twin: resumed: 2 of 2 chunks kept")


def test_turned_off_the_report_says_how_to_measure_it(tmp_path):
    """fixed_twin = false: no twin, the report says the widening was not measured and how;
    turned on again, the run keeps its drapes (the key does not change them) and drapes
    the twin only."""
    zero = dict(IID, sd_dof=6.0)
    _, out = _run(tmp_path, "hier", zero, report={"fixed_twin": False})
    assert not (out / "fixed").exists()
    said = _said(out)
    assert said[MEASURED] == {"value": "not measured", "how": "[report] fixed_twin = false; run the study again "
                              "with [report] fixed_twin = true (the default) to drape its twin into fixed/ (the "
                              "run's own drapes are kept)"}
    assert SD_WIDER not in said and SHARE not in said
    chunks = {p.name: p.stat().st_mtime_ns for p in (out / "chunks").iterdir()}
    _run(tmp_path, "hier", zero)
    assert {p.name: p.stat().st_mtime_ns for p in (out / "chunks").iterdir()} == chunks
    assert read_manifest(out / "fixed")["last_call"]["drawn"] == 2
    assert MEDIAN.fullmatch(_said(out)[SD_WIDER]["value"])


def test_a_twin_of_fewer_realisations_is_not_used(tmp_path):
    """The run extended to 48 realisations with fixed_twin = false: its 32-realisation twin
    is not this run's, and the report says so."""
    zero = dict(IID, sd_dof=6.0)
    _run(tmp_path, "hier", zero)
    _, out = _run(tmp_path, "hier", zero, report={"fixed_twin": False}, study={"realizations": 48})
    assert _said(out)[MEASURED]["how"].startswith("fixed/ holds 32 of the run's 48 realisations; run the study")


def test_a_target_run_s_twin_matches_its_final_count(tmp_path):
    """A target out of reach: rounds of 16 up to the budget of 48; the twin has 48."""
    target = {"target": {"qoi": "max_abs_shear", "statistic": "mean", "half_width": 1e-9}, "max_realizations": 48,
              "realizations": 16}
    _, out = _run(tmp_path, "goal", dict(IID, sd_dof=6.0), study=target)
    assert read_manifest(out)["target"]["realizations"] == 48
    assert read_manifest(out / "fixed")["study"]["study"]["realizations"] == 48
    assert _said(out)[MEASURED]["value"].startswith("48 realisations, ")


def test_a_fixed_sd_study_has_no_twin(tmp_path):
    _, out = _run(tmp_path, "plain", IID)
    assert not (out / "fixed").exists() and _said(out) == {}
    assert load_study(tmp_path / "plain.toml").report.fixed_twin is None


def test_the_preflight_counts_the_twin_s_drapes(tmp_path, capsys, monkeypatch):
    """Disk for the run's 32 drapes but not for the twin's too: refused before any drape;
    without the twin it runs."""
    free = 40 * 169 * preflight.STORED_BYTES_PER_NODE
    monkeypatch.setattr(shutil, "disk_usage", lambda path: SimpleNamespace(free=free))
    path = write_study(tmp_path, "hier", **SMALL, uncertainty={"zero_angle": dict(IID, sd_dof=6.0)})
    assert main(["validate", str(path)]) == 2
    assert_one_line_error(capsys.readouterr().err, file=path.name, key="study.realizations", valid=("64 drapes",))
    off = write_study(tmp_path, "off", **SMALL, uncertainty={"zero_angle": dict(IID, sd_dof=6.0)},
                      report={"fixed_twin": False})
    assert main(["validate", str(off)]) == 0


def test_a_bad_fixed_twin_is_one_line(tmp_path, capsys):
    key = "report.fixed_twin"
    drawn = {"zero_angle": dict(IID, sd_dof=6.0)}
    design = {"variables": "force", "force_bounds_N": [0.0, 300.0], "objective": "abs_mean_asymmetry",
              "target": 1.0}
    for uncertainty, value, sections, valid in (
            (drawn, "yes", {}, ("true or false",)),
            ({"zero_angle": IID}, True, {}, ("sd_dof or length_log_sd",)),
            ({"zero_angle": IID}, False, {}, ("sd_dof or length_log_sd",)),
            (drawn, True, {"design": design}, ("[design]",))):
        path = write_study(tmp_path, "bad", **SMALL, uncertainty=uncertainty, report={"fixed_twin": value}, **sections)
        assert main(["validate", str(path)]) == 2, (uncertainty, value, sections)
        assert_one_line_error(capsys.readouterr().err, file=path.name, key=key, valid=valid)


def test_a_store_s_twin_is_under_its_url(tmp_path, capsys):
    """A run into a file:// store drapes its twin into URL/fixed, and its report measures
    the widening from the two stores."""
    url = f"file://{tmp_path}/store"
    path = write_study(tmp_path, "hier", **SMALL, uncertainty={"zero_angle": dict(IID, sd_dof=6.0)})
    assert main(["run", str(path), "--out", url, "--scheduler", "synchronous", "-q"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1] == f"fixed-parameter twin: ensemble written to {url}/fixed: 2 chunks drawn"
    assert read_manifest(f"{url}/fixed")["study"]["study"]["realizations"] == 32
    page = (tmp_path / "store" / "report" / "index.html").read_text(encoding="utf-8")
    assert "32 realisations, " in page and "node-shear sd wider than the twin&#x27;s by" in page
