"""Every documented command runs verbatim on a fresh clone (issue 27; the README's Python
example is run by tests/test_api.py).

The convention, as docs/getting-started.md states it: each line of a ```bash block is a
command (a line ending in a backslash continues on the next; blank and comment-only lines
are skipped), and the blocks run in order, in one bash shell, from the root of a fresh
``git clone`` of the committed checkout, as a user would type them: the README's first,
then the documentation's pages in the order of their table of contents (``PAGES``);
```console blocks are not run. A line that runs the test suite (one naming pytest) is not
run here, where it would run this test again: CI runs those lines, and the default suite
checks that each is a line of ``.ci/run`` as written.

The slow test needs git, python3 on PATH and what ``pip install -e .`` needs (pip's cache
or index); it compiles the numba kernels afresh in the clone, as a new user's first drape
does.
"""

from __future__ import annotations

import os
import re
import resource
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
#: The documented pages whose ```bash blocks run after the README's, in the order a reader meets them.
PAGES = ("docs/getting-started.md", "docs/user-guide/study-files.md", "docs/user-guide/moulds.md",
         "docs/user-guide/materials.md", "docs/user-guide/variability.md", "docs/user-guide/ensembles.md",
         "docs/user-guide/statistics.md", "docs/user-guide/designs.md", "docs/user-guide/reports-exports.md",
         "docs/how-to/own-mould.md", "docs/how-to/own-card.md", "docs/how-to/measurements.md",
         "docs/how-to/cluster.md", "docs/how-to/s3.md")
#: A line that runs the test suite.
TEST_SUITE = re.compile(r"\bpytest\b")
#: Environment a user's fresh shell would not have: this session's interpreter and caches.
FOREIGN = ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "NUMBA_CACHE_DIR", "PYTEST_ADDOPTS")


def bash_commands(text: str) -> list[tuple[int, str]]:
    """(line number, command) of every command of the ```bash blocks of ``text``, in order:
    continuation lines joined, blank and comment-only lines dropped."""
    commands, inside, pending = [], False, None
    for number, line in enumerate(text.splitlines(), 1):
        if not inside:
            inside = line.strip() == "```bash"
            continue
        if line.strip().startswith("```"):  # a fence may be indented (a block inside a list)
            inside = False
            continue
        if pending is not None:
            start, line = pending[0], pending[1] + " " + line.strip()
        else:
            start = number
        if line.rstrip().endswith("\\"):
            pending = (start, line.rstrip()[:-1].rstrip())
            continue
        pending = None
        if line.strip() and not line.lstrip().startswith("#"):
            commands.append((start, line.strip()))
    return commands


def user_commands(text: str) -> list[tuple[int, str]]:
    """The commands of ``bash_commands`` this test runs: all but the test-suite lines."""
    return [(n, c) for n, c in bash_commands(text) if not TEST_SUITE.search(c)]


def documented_commands(root: Path) -> list[tuple[str, str]]:
    """("FILE:LINE", command) of every command this test runs: the README's, then ``PAGES``',
    each distinct command once (a how-to repeats commands of the user guide)."""
    commands = {}
    for name in ("README.md", *PAGES):
        for n, c in user_commands((root / name).read_text(encoding="utf-8")):
            commands.setdefault(c, f"{name}:{n}")
    return [(where, c) for c, where in commands.items()]


def script(commands: list[tuple[str, str]]) -> str:
    """A bash script running ``commands`` one after the other, each between two marker lines
    (``>>> FILE:N START_TIME``, ``<<< FILE:N EXIT_CODE END_TIME``), stopping at the first
    that fails."""
    lines = []
    for where, command in commands:
        lines += [f"echo \">>> {where} $EPOCHREALTIME {shlex.quote(command)}\"", command,
                  f"rc=$?; echo \"<<< {where} $rc $EPOCHREALTIME\"; [ $rc -eq 0 ] || exit $rc"]
    return "\n".join(lines) + "\n"


def timings(log: str) -> list[tuple[str, float]]:
    """(FILE:LINE, seconds) of every command the log shows finished."""
    starts = {m[1]: float(m[2]) for m in re.finditer(r"^>>> (\S+:\d+) ([\d.]+)", log, re.M)}
    return [(m[1], float(m[3]) - starts[m[1]]) for m in re.finditer(r"^<<< (\S+:\d+) (\d+) ([\d.]+)", log, re.M)]


def fresh_environment() -> dict:
    """os.environ without this session's interpreter: no PYTHONPATH, no active venv on PATH."""
    env = {k: v for k, v in os.environ.items() if k not in FOREIGN}
    if sys.prefix != sys.base_prefix:
        venv_bin = str(Path(sys.prefix) / "bin")
        env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if p != venv_bin)
    return env


def test_bash_blocks_are_read_as_the_readme_says():
    text = "\n".join([
        "# title", "```bash", "# a comment", "uqdrape a   # trailing comment", "", "uqdrape b \\",
        "    --long \\", "    --longer", "```", "```console", "uqdrape scheduler-only", "```",
        "```python", "print(1)", "```", "```bash", "python3 -m venv .venv && .venv/bin/python -m pytest -n 2",
        "uqdrape c", "```"])
    assert bash_commands(text) == [(4, "uqdrape a   # trailing comment"), (6, "uqdrape b --long --longer"),
                                   (17, "python3 -m venv .venv && .venv/bin/python -m pytest -n 2"),
                                   (18, "uqdrape c")]
    assert user_commands(text) == [(4, "uqdrape a   # trailing comment"), (6, "uqdrape b --long --longer"),
                                   (18, "uqdrape c")]


def test_the_script_stops_at_the_first_failing_command(tmp_path):
    """A failure inside an && list (which ``set -e`` would let pass) stops the run there,
    and the log shows which README line it was; a later line never runs."""
    commands = [("README.md:3", "echo one > a.txt   # a comment"), ("README.md:7", "true && false && echo never"),
                ("docs/x.md:9", "touch b.txt")]
    (tmp_path / "s.sh").write_text(script(commands))
    done = subprocess.run(["bash", "s.sh"], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 1 and (tmp_path / "a.txt").read_text() == "one\n"
    assert not (tmp_path / "b.txt").exists() and "never" not in done.stdout.splitlines()
    assert [n for n, _ in timings(done.stdout)] == ["README.md:3", "README.md:7"] and "<<< README.md:7 1 " in done.stdout


def test_the_test_suite_lines_are_what_ci_runs():
    """The README lines this file does not run are run by CI: each is a line of .ci/run."""
    commands = bash_commands(README.read_text(encoding="utf-8"))
    suite = [c for _, c in commands if TEST_SUITE.search(c)]
    ci = {line.strip() for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()}
    assert suite and all(c in ci for c in suite), suite
    assert len(documented_commands(ROOT)) >= 20  # the examples of the README and the pages are left to run


def test_the_pages_run_are_the_documentation_pages_with_commands():
    """Every page of docs/ with a ```bash block is in PAGES (none would be left unrun)."""
    with_commands = {str(p.relative_to(ROOT)) for p in (ROOT / "docs").rglob("*.md")
                     if bash_commands(p.read_text(encoding="utf-8"))}
    assert with_commands <= set(PAGES), sorted(with_commands - set(PAGES))
    assert all((ROOT / page).is_file() for page in PAGES)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_every_readme_command_runs_verbatim_on_a_fresh_clone(tmp_path):
    if not (ROOT / ".git").exists() or shutil.which("git") is None:
        pytest.skip("not a git checkout: the test clones the committed checkout")
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                          check=True).stdout.strip()
    clone = tmp_path / "uqdrape"
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
    subprocess.run(["git", "-C", str(clone), "checkout", "--quiet", "--detach", head], check=True)
    commands = documented_commands(clone)
    (tmp_path / "readme.sh").write_text(script(commands), encoding="utf-8")
    log_path = tmp_path / "readme.log"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(log_path, "w", encoding="utf-8") as log:
        done = subprocess.run(["bash", str(tmp_path / "readme.sh")], cwd=clone, env=fresh_environment(),
                              stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    log = log_path.read_text(encoding="utf-8", errors="replace")
    times = timings(log)
    print(f"documented commands of {head[:7]} in {clone}:")
    for (where, command), (_, seconds) in zip(commands, times):
        print(f"  {seconds:6.1f} s  {where}  {command[:100]}")
    print(f"  {sum(t for _, t in times):6.1f} s  in all, {cpu:.1f} s of CPU (user + sys of the processes the shell waited for)")
    if done.returncode != 0:
        where, command = commands[len(times) - 1] if times else commands[0]
        tail = "\n".join(log.splitlines()[-25:])
        pytest.fail(f"{where} exits {done.returncode} on a fresh clone ({clone}):\n{command}\n"
                    f"--- last lines of {log_path}:\n{tail}")
    assert len(times) == len(commands)
    # every example writes under an ignored folder (results/, .venv/): none into the checkout
    stray = subprocess.run(["git", "-C", str(clone), "status", "--porcelain", "--untracked-files=all"],
                           capture_output=True, text=True, check=True).stdout
    assert stray == "", f"documented commands wrote into the checkout:\n{stray}"
    shutil.rmtree(clone)  # a venv of about a gigabyte; kept when the test fails

