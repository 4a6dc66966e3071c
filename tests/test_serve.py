"""``uqdrape serve``: a study as a UM-Bridge model, driven by the umbridge client on
loopback. The server runs in a subprocess on a free port, stops by itself after two
evaluations (or 240 s), and the test kills it in a finally if it has not.
"""

import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import write_study

from uqdrape.cli import main
from uqdrape.export import open_result
from uqdrape.stats.qoi import realization_qois
from uqdrape.workflow import input_names, load_study, nominal_input

umbridge = pytest.importorskip("umbridge")
requests = pytest.importorskip("requests")

QOI = ["max_abs_shear", "asymmetry", "blankholder_energy", "max_draw_in"]
SECTIONS = {
    "process": {"blankholder_force_N": 100.0, "friction": 0.2, "blankholder_model": "slip"},
    "solver": {"mode": "energy", "rings": 6},
    "uncertainty": {"friction": {"dist": "uniform", "bounds": [0.15, 0.3]},
                    "orientation": {"dist": "normal", "mean": 0.0, "sd": 2.0}},
}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until_up(url, proc, seconds=120.0):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise AssertionError(f"the server exited with {proc.returncode} before answering")
        try:
            if requests.get(f"{url}/Info", timeout=2).ok:
                return
        except requests.ConnectionError:
            time.sleep(0.3)
    raise AssertionError(f"no UM-Bridge server at {url} after {seconds} s")


def test_inputs_are_the_factors_then_the_fields_modes(tmp_path):
    study = load_study(write_study(tmp_path, **SECTIONS))
    assert input_names(study) == ["friction", "orientation"]
    assert nominal_input(study) == pytest.approx([0.225, 0.0], abs=1e-15)
    field = dict(SECTIONS, uncertainty=dict(SECTIONS["uncertainty"], zero_angle={
        "mean_deg": 0.0, "sd_deg": 2.0, "correlation": "squared_exponential", "length_mm": [20.0, 20.0],
        "kl_retained": 0.9}))
    names = input_names(load_study(write_study(tmp_path, name="field", **field)))
    assert names[:2] == ["friction", "orientation"] and names[2] == "zero_angle[0]" and len(names) > 3


def test_umbridge_client_at_the_nominal_input_equals_uqdrape_drape(tmp_path):
    path = write_study(tmp_path, **SECTIONS)
    study = load_study(path)
    x0 = nominal_input(study)
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    out, err = (tmp_path / "server.out").open("w"), (tmp_path / "server.err").open("w")
    proc = subprocess.Popen([sys.executable, "-m", "uqdrape.cli", "serve", str(path), "--port", str(port),
                             "--max-requests", "2", "--timeout", "240", "--qoi", *QOI], stdout=out, stderr=err)
    try:
        wait_until_up(url, proc)
        model = umbridge.HTTPModel(url, "forward")
        assert model.get_input_sizes() == [2] and model.get_output_sizes() == [len(QOI)]
        (served,) = model([x0])
        with pytest.raises(Exception, match="friction = -1 is invalid"):  # the protocol's error, not counted
            model([[-1.0, 0.0]])
        (other,) = model([[0.3, x0[1]]])  # the second and last evaluation: more friction
        assert proc.wait(timeout=60) == 0  # it stopped by itself
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        out.close()
        err.close()
    text = (tmp_path / "server.out").read_text()
    assert "friction ~ uniform" in text and "served 2 evaluations" in text
    stem = tmp_path / "drape"
    assert main(["drape", "--mode", "energy", "--material", "generic_woven", "--geometry", "hemisphere",
                 "--param", "radius=50", "--spacing", "5", "--rings", "6", "--blankholder-force", "100",
                 "--friction", repr(x0[0]), "--orientation", repr(x0[1]), "--blankholder-model", "slip",
                 "--out", str(stem), "-q"]) == 0
    ds, _ = open_result(stem.with_suffix(".nc"))
    q = realization_qois(ds, QOI)
    expected = [float(q[name].values.ravel()[0]) for name in QOI]
    assert served == expected  # the same drape, bit for bit
    assert other[QOI.index("blankholder_energy")] > served[QOI.index("blankholder_energy")]


def test_bad_arguments_are_one_line(tmp_path, capsys):
    path = write_study(tmp_path, **SECTIONS)
    assert main(["serve", str(path), "--max-requests", "0"]) == 2
    assert main(["serve", str(path), "--qoi", "nonsense"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and "--max-requests" in err[0] and "max_abs_shear" in err[1]
    assert np.all([line.startswith("uqdrape serve: error:") for line in err])


def test_a_taken_port_is_an_environment_error(tmp_path, capsys):
    path = write_study(tmp_path, **SECTIONS)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        assert main(["serve", str(path), "--port", str(busy.getsockname()[1])]) == 3
    assert "uqdrape serve: error:" in capsys.readouterr().err


def test_a_sweep_answers_one_vector_per_force_level_and_fields_take_their_modes(tmp_path):
    from uqdrape.workflow.serve import evaluate

    sweep = load_study(write_study(tmp_path, name="sweep", **dict(SECTIONS, process=dict(
        SECTIONS["process"], blankholder_force_N=[0.0, 200.0]))))
    low, high = evaluate(sweep, [0.2, 0.0], QOI)
    energy = QOI.index("blankholder_energy")
    assert low[energy] == 0.0 < high[energy]  # no force, no blank-holder work
    field = load_study(write_study(tmp_path, name="field", **dict(SECTIONS, uncertainty=dict(
        SECTIONS["uncertainty"], zero_angle={"mean_deg": 0.0, "sd_deg": 5.0, "correlation": "squared_exponential",
                                             "length_mm": [20.0, 20.0], "kl_retained": 0.9}))))
    x = nominal_input(field)
    (at_mean,) = evaluate(field, x, QOI)
    x[2] = 2.0  # the first KL mode two standard deviations out shifts the zero angle
    (moved,) = evaluate(field, x, QOI)
    assert at_mean != moved
    with pytest.raises(ValueError, match="zero_angle"):
        evaluate(field, x[:-1], QOI)
