"""The CLI around a run: --version, run --out, progress counted in realisations (no
carriage returns off a terminal), the report-phase line, -q / -v; a single drape's ring
counter."""

import io
import textwrap

import pytest

from uqdrape import __version__
from uqdrape.cli import main
from uqdrape.ensemble.progress import Progress


def test_version(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0 and capsys.readouterr().out.startswith(f"uqdrape {__version__}")


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_progress_is_a_bar_on_a_terminal_and_plain_lines_elsewhere():
    log = io.StringIO()
    bar = Progress(10, 2, file=log, desc="study")
    bar.update(4)
    bar.update(4, "r0.nc")
    bar.close()
    text = log.getvalue()
    assert "\r" not in text and text.splitlines()[-1].startswith("study: 100%") and "10/10" in text
    tty = Terminal()
    bar = Progress(10, file=tty, desc="study")
    bar.update(10)
    bar.close()
    assert "\r" in tty.getvalue() and "10/10" in tty.getvalue()
    quiet = io.StringIO()
    Progress(10, file=quiet, enabled=False).update(10)
    assert quiet.getvalue() == ""


@pytest.fixture()
def study(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(textwrap.dedent("""
        [study]
        name = "tiny"
        seed = 1
        realizations = 6
        chunk_size = 3
        [geometry]
        kind = "plate"
        [fabric]
        material = "generic_woven"
        spacing_mm = 5.0
        [process]
        blankholder_force_N = 0.0
        [solver]
        mode = "geodesic"
        rings = 3
        [uncertainty.spacing]
        cv = 0.01
        [output]
        directory = "never-used"
    """))
    return path


@pytest.mark.parametrize("flags", [[], ["-q"], ["-v"]])
def test_run_out_progress_and_verbosity(study, tmp_path, capsys, flags):
    out = tmp_path / "elsewhere"
    assert main(["run", str(study), "--out", str(out), "--scheduler", "synchronous", "--no-report", *flags]) == 0
    std = capsys.readouterr()
    assert (out / "chunks" / "r0000000-0000002.nc").is_file() and not (tmp_path / "never-used").exists()
    assert f"ensemble written to {out.absolute()}" in std.out
    if flags == ["-q"]:
        assert std.err == ""
    else:
        assert "\r" not in std.err and "tiny: 100%" in std.err and "6/6" in std.err
        assert ("finished r0000003-0000005.nc" in std.err) == (flags == ["-v"])


def test_report_phase_has_its_line(study, tmp_path, capsys, monkeypatch):
    import uqdrape.workflow

    monkeypatch.setattr(uqdrape.workflow, "run_report", lambda out: out / "report" / "index.html")
    assert main(["-q", "run", str(study), "--out", str(tmp_path / "a"), "--scheduler", "synchronous",
                 "--no-report"]) == 0
    assert capsys.readouterr().err == ""  # -q before the sub-command too
    assert main(["run", str(study), "--out", str(tmp_path / "a"), "--scheduler", "synchronous"]) == 0
    err = capsys.readouterr().err
    assert "tiny: 2 of 2 chunks already done" in err and "tiny: writing the report" in err


@pytest.mark.parametrize("terminal", [False, True])
@pytest.mark.parametrize("quiet", [False, True])
def test_single_drape_counts_its_rings_on_stderr(tmp_path, capsys, monkeypatch, quiet, terminal, unrasterised):
    """``uqdrape drape --mode energy`` counts "ring k/n" on stderr: a bar on a terminal,
    elsewhere a plain line every PLAIN_EVERY s (here 0: every ring); -q hides it. stdout
    keeps only the summary."""
    import uqdrape.ensemble.progress

    monkeypatch.setattr(uqdrape.ensemble.progress, "PLAIN_EVERY", 0.0)
    monkeypatch.setattr(uqdrape.ensemble.progress, "compile_pending", lambda mode: False)  # its line: below
    tty = Terminal()
    if terminal:
        monkeypatch.setattr("sys.stderr", tty)
    argv = ["drape", "--mode", "energy", "--material", "ebxhd936_like", "--geometry", "nose_cone",
            "--rings", "4", "--blankholder-force", "126", "--out", str(tmp_path / "nose")]
    assert main(argv + ["-q"] if quiet else argv) == 0
    std = capsys.readouterr()
    err = tty.getvalue() if terminal else std.err
    assert "ring" not in std.out and std.out.startswith("wrote ")
    if quiet:
        assert err == ""
    elif terminal:
        assert "\r" in err and "ring:" in err and "4/4" in err
    else:
        assert [line.split("|")[-1].split()[0] for line in err.splitlines()] == ["1/4", "2/4", "3/4", "4/4"]
        assert all(line.startswith("ring: ") for line in err.splitlines()) and "\r" not in err


def test_a_short_drape_off_a_terminal_leaves_stderr_to_errors(tmp_path, capsys, monkeypatch):
    """Off a terminal a drape shorter than PLAIN_EVERY writes no counter line, so a failure
    after the drape is still one line on stderr."""
    monkeypatch.setattr("uqdrape.ensemble.progress.compile_pending", lambda mode: False)
    assert main(["drape", "--rings", "3", "--out", str(tmp_path / "d")]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("pending", [False, True])
@pytest.mark.parametrize("quiet", [False, True])
def test_a_drape_says_when_it_must_compile_its_kernels_first(tmp_path, capsys, monkeypatch, pending, quiet):
    """While numba's cache lacks the kernels (issue 40: a fresh clone's first drape stood
    at ring 0/30 for ~22 s), the drape says so before its first ring; -q keeps it quiet."""
    seen = []
    monkeypatch.setattr("uqdrape.ensemble.progress.compile_pending", lambda mode: seen.append(mode) or pending)
    argv = ["drape", "--rings", "3", "--out", str(tmp_path / "d")]
    assert main(argv + ["-q"] if quiet else argv) == 0
    err = capsys.readouterr().err
    assert err == ("compiling the drape kernels (once, about 15 s)\n" if pending and not quiet else "")
    assert seen == ([] if quiet else ["geodesic"])


@pytest.mark.parametrize("quiet", [False, True])
def test_a_run_says_when_its_workers_must_compile_the_kernels_first(tmp_path, capsys, monkeypatch, quiet):
    """A run on a cold numba cache (a fresh clone) says so before its workers start: its
    first chunk carries the compiling. A run with nothing left to drape says nothing."""
    from conftest import write_study

    monkeypatch.setattr("uqdrape.ensemble.progress.compile_pending", lambda mode: mode == "geodesic")
    study = write_study(tmp_path, study={"realizations": 2}, solver={"mode": "geodesic", "rings": 3})
    argv = ["run", str(study), "--scheduler", "synchronous", "--no-report"] + (["-q"] if quiet else [])
    for again in (False, True):
        assert main(argv) == 0
        said = "tiny: compiling the drape kernels (once, about 15 s)" in capsys.readouterr().err
        assert said == (not quiet and not again)


@pytest.mark.parametrize("terminal", [False, True])
def test_the_eta_comes_from_finished_work_after_the_first_ring(monkeypatch, terminal):
    """A cold drape's first ring carries ~30 s of compiling and the 29 after it take 0.3 s
    each: no ETA until the second ring, then 29 x 0.3 s, not 29 x 32 s (issue 40: an
    11-minute ETA)."""
    import uqdrape.ensemble.progress as progress

    now = [0.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: now[0])
    monkeypatch.setattr(progress, "PLAIN_EVERY", 0.0)
    monkeypatch.setattr(progress, "compile_pending", lambda mode: False)
    out = Terminal() if terminal else io.StringIO()
    bar = progress.ring_progress(30, "energy", file=out)
    lines = []
    for now[0] in (32.0, 32.3):
        bar.update(1)
        lines.append(str(bar.bar) if terminal else out.getvalue().splitlines()[-1])  # tqdm's line, not its timing
    assert "1/30" in lines[0] and "<?," in lines[0] and "?ring/s" in lines[0], lines
    assert "2/30" in lines[1] and "<00:08," in lines[1] and "3.33ring/s" in lines[1], lines


def test_a_resumed_run_says_what_it_kept_and_a_log_sees_the_start(study, tmp_path, capsys, monkeypatch):
    """A fresh run counts the chunks it drew, a resume the chunks it kept; off a terminal
    the first progress line (0 or the kept count) is written before any drape finishes
    (the kernels taken as compiled: a cold cache puts its notice first)."""
    from uqdrape.ensemble import progress

    monkeypatch.setattr(progress, "compile_pending", lambda mode: False)
    out = tmp_path / "r"
    argv = ["run", str(study), "--out", str(out), "--scheduler", "synchronous", "--no-report"]
    assert main(argv) == 0
    std = capsys.readouterr()
    assert f"ensemble written to {out.absolute()}: 2 chunks drawn" in std.out
    assert std.err.splitlines()[0].startswith("tiny:") and "0/6" in std.err.splitlines()[0]
    (out / "chunks" / "r0000003-0000005.nc").unlink()
    assert main(argv) == 0
    std = capsys.readouterr()
    assert f"resumed: 1 of 2 chunks kept, 1 drawn; ensemble in {out.absolute()}" in std.out
    assert "ensemble written" not in std.out and "3/6" in std.err.splitlines()[1]


def test_run_help_has_examples_and_exit_codes(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = capsys.readouterr().out
    assert "examples:\n  uqdrape run studies/nosecone-zero-angle.toml" in text and "--no-resume" in text
    assert all(f"\n  {code}  " in text for code in ("0", "2", "3", "130"))


def test_messages_name_flags_not_python_keywords(study, tmp_path, capsys):
    out = tmp_path / "k"
    argv = ["run", str(study), "--out", str(out), "--scheduler", "synchronous", "--no-report", "-q"]
    assert main(argv) == 0
    assert main(argv + ["--chunk-size", "2"]) == 2
    err = capsys.readouterr().err
    assert "error: --chunk-size and --no-resume: " in err and "in chunks of 3; resume with that chunk size" in err
    assert "=False" not in err and "chunk_size" not in err
    assert main(["drape", "--mode", "energy", "--rings", "3", "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "error: --material: mode 'energy' needs a material card" in err and "load_material" not in err
