"""Every README command runs verbatim on a fresh clone (issue 27).

The convention, as README.md states it near the top: each line of a ```bash block is a
command (a line ending in a backslash continues on the next; blank and comment-only lines
are skipped), and the blocks run in order, in one bash shell, from the root of a fresh
``git clone`` of the committed checkout, as a user would type them; ```console blocks are
not run. A line that runs the test suite (one naming pytest) is not run here, where it
would run this test again: CI runs those lines, and the default suite checks that each is
a line of ``.ci/run`` as written.

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
        if line.startswith("```"):
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


def script(commands: list[tuple[int, str]]) -> str:
    """A bash script running ``commands`` one after the other, each between two marker lines
    (``>>> README.md:N START_TIME``, ``<<< README.md:N EXIT_CODE END_TIME``), stopping at
    the first that fails."""
    lines = []
    for number, command in commands:
        lines += [f"echo \">>> README.md:{number} $EPOCHREALTIME {shlex.quote(command)}\"", command,
                  f"rc=$?; echo \"<<< README.md:{number} $rc $EPOCHREALTIME\"; [ $rc -eq 0 ] || exit $rc"]
    return "\n".join(lines) + "\n"


def timings(log: str) -> list[tuple[int, float]]:
    """(README line, seconds) of every command the log shows finished."""
    starts = {int(m[1]): float(m[2]) for m in re.finditer(r"^>>> README\.md:(\d+) ([\d.]+)", log, re.M)}
    return [(int(m[1]), float(m[3]) - starts[int(m[1])])
            for m in re.finditer(r"^<<< README\.md:(\d+) (\d+) ([\d.]+)", log, re.M)]


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
    commands = [(3, "echo one > a.txt   # a comment"), (7, "true && false && echo never"), (9, "touch b.txt")]
    (tmp_path / "s.sh").write_text(script(commands))
    done = subprocess.run(["bash", "s.sh"], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 1 and (tmp_path / "a.txt").read_text() == "one\n"
    assert not (tmp_path / "b.txt").exists() and "never" not in done.stdout.splitlines()
    assert [n for n, _ in timings(done.stdout)] == [3, 7] and "<<< README.md:7 1 " in done.stdout


def test_the_test_suite_lines_are_what_ci_runs():
    """The README lines this file does not run are run by CI: each is a line of .ci/run."""
    commands = bash_commands(README.read_text(encoding="utf-8"))
    suite = [c for _, c in commands if TEST_SUITE.search(c)]
    ci = {line.strip() for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()}
    assert suite and all(c in ci for c in suite), suite
    assert len(commands) - len(suite) >= 10  # the README's own examples are left to run


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
    commands = user_commands((clone / "README.md").read_text(encoding="utf-8"))
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
    print(f"README commands of {head[:7]} in {clone}:")
    for (number, command), (_, seconds) in zip(commands, times):
        print(f"  {seconds:6.1f} s  README.md:{number}  {command[:100]}")
    print(f"  {sum(t for _, t in times):6.1f} s  in all, {cpu:.1f} s of CPU (user + sys of the processes the shell waited for)")
    if done.returncode != 0:
        number, command = commands[len(times) - 1] if times else commands[0]
        tail = "\n".join(log.splitlines()[-25:])
        pytest.fail(f"README.md:{number} exits {done.returncode} on a fresh clone ({clone}):\n{command}\n"
                    f"--- last lines of {log_path}:\n{tail}")
    assert len(times) == len(commands)
    # every example writes under an ignored folder (results/, .venv/): none into the checkout
    stray = subprocess.run(["git", "-C", str(clone), "status", "--porcelain", "--untracked-files=all"],
                           capture_output=True, text=True, check=True).stdout
    assert stray == "", f"README commands wrote into the checkout:\n{stray}"
    shutil.rmtree(clone)  # a venv of about a gigabyte; kept when the test fails
