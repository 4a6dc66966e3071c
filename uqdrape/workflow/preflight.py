"""What a study needs of this machine and of its physics, checked before anything is
draped: at the start of every run and design, and by ``uqdrape validate``.

The study file itself is checked where it is read (``uqdrape.study.load_study``: keys,
types, ranges, the rules tying sections together); this is what reading a file cannot
know: the memory a chunk takes, the disk the chunks still to be written take in the
folder that will actually be written, whether that folder is writable, and whether the
first realisation's net can be placed on the mould at all. A run to a target
(``[study] target``) is checked for its budget, ``max_realizations``: the largest chunk
any of its rounds drapes, and every drape its rounds may still write. Every refusal is a
``StudyError`` naming the study file and the key to change.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import numpy as np

from ..drape import placement_failures, unplaced_error
from ..errors import ParameterError
from ..ensemble import inputs_from_rows, placement_status, ply_inputs, sampled_inputs
from ..ensemble import at
from ..study import load_study, study_error

#: Bytes a node costs in a chunk file (x, y, z, shear, locked, status and the cells' values)
#: and, about, in the solver's working arrays of an energy drape (candidate rings per step).
STORED_BYTES_PER_NODE = 64
WORKING_BYTES_PER_NODE = 600


#: Most local worker processes per CPU core: more only queue for the cores and each holds
#: its own interpreter and kernels (about 200 MB).
WORKERS_PER_CORE = 4


def check_workers(workers: int | None) -> None:
    """Refuse a ``--workers`` below 1 or above WORKERS_PER_CORE per core of this machine,
    before any process is spawned."""
    most = WORKERS_PER_CORE * (os.cpu_count() or 1)
    if workers is not None and not 1 <= workers <= most:
        raise ParameterError("workers", f"workers must be from 1 to {most} ({WORKERS_PER_CORE} per core of this "
                             f"machine's {os.cpu_count() or 1}), got {workers}; a cluster takes a scheduler address")


def memory_bytes() -> int:
    """This machine's physical memory (bytes)."""
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def nearest_existing(path: Path) -> Path:
    """``path`` (absolute) or its nearest ancestor that exists: where a folder will be made."""
    path = Path(path).absolute()
    while not path.exists():
        path = path.parent
    return path


def budget(study) -> tuple[str, int]:
    """(key, realisations) a run of ``study`` may reach: ``study.max_realizations`` for a
    run to a target, else ``study.realizations``."""
    if study.target is not None:
        return "study.max_realizations", study.max_realizations
    return "study.realizations", study.realizations


def check_resources(study, output_dir, drapes_to_write: int, chunk_size: int | None = None) -> None:
    """Refuse a study whose drape or chunk would not fit in memory, whose output folder
    cannot be written, or whose ``drapes_to_write`` drapes would not fit on that folder's
    disk (estimates, stated in the message). The chunk is the largest the study's
    :func:`budget` of realisations makes. ``output_dir`` a store's URL: the store must
    take a write (``ZarrStore.probe``: OSError otherwise); an object store's space is
    not known here, a file:// store's folder is checked as a folder."""
    nodes = (2 * study.solver.rings + 1) ** 2
    memory = memory_bytes()
    if nodes * WORKING_BYTES_PER_NODE > memory / 2:
        raise study_error(study.path, "solver.rings", study.solver.rings,
                          f"one drape of {nodes:,} nodes needs about {nodes * WORKING_BYTES_PER_NODE / 2**30:.3g} "
                          f"GiB, more than half of this machine's {memory / 2**30:.3g} GiB")
    chunk_size = study.chunk_size if chunk_size is None else chunk_size
    key, most = budget(study)
    batch = min(chunk_size, most)
    need = batch * nodes * WORKING_BYTES_PER_NODE
    if need > memory / 2:
        raise study_error(study.path, "study.chunk_size", chunk_size,
                          f"a chunk of {batch} drapes of {nodes:,} nodes needs about {need / 2**30:.3g} GiB, more "
                          f"than half of this machine's {memory / 2**30:.3g} GiB; use a smaller chunk_size")
    where = at(output_dir)
    where.probe()
    output_dir = where.local_folder()
    if output_dir is None:
        return
    existing = nearest_existing(output_dir)
    if not existing.is_dir():
        raise study_error(study.path, "output.directory", str(output_dir), f"{existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise study_error(study.path, "output.directory", str(output_dir), f"{existing} is not writable")
    disk = drapes_to_write * nodes * STORED_BYTES_PER_NODE
    free = shutil.disk_usage(existing).free
    if disk > free:
        raise study_error(study.path, key, most,
                          f"{drapes_to_write:,} drapes of {nodes:,} nodes take about {disk / 2**30:.3g} GiB, "
                          f"more than the {free / 2**30:.3g} GiB free under {existing}")


#: Share of the first realisation's nodes not placed above which a run or validate says so
#: on stderr, within the failure budget (a square net's corners off a round mould are a
#: few per cent; a pre-sheared or oversized net past this is worth a look).
WARN_UNPLACED = 0.10


def check_placement(study, realization: int = 0, force: float | None = None, sample_rows=None, *,
                    quiet: bool = False) -> None:
    """Drape one realisation of the study (row ``realization`` of ``sample_rows`` if
    given) here, before any worker starts, and refuse the study if more than its
    ``[solver] failure_budget`` of the nodes cannot be placed: such a run would only write
    NaNs (the crossover off the mould, a net larger than the mould). Within the budget,
    more than WARN_UNPLACED of them is a warning on stderr (unless ``quiet``)."""
    r = np.arange(realization, realization + 1)
    force = study.force_levels[0] if force is None else force
    if study.plies:  # each ply from its seed point: a ply that cannot be placed is named
        for k, ply in enumerate(study.plies):
            status = placement_status(study.ply_study(k), r, ply_inputs(study, k, r), force=force)[0]
            _placed(study, status, realization, f"ply.{ply.name}.crossover", list(ply.crossover), quiet,
                    f"ply {ply.name}: ")
        return
    inputs = sampled_inputs(study, r) if sample_rows is None else inputs_from_rows(study, sample_rows[r])
    status = placement_status(study, r, inputs, force=force)[0]
    _placed(study, status, realization, "solver.rings", study.solver.rings, quiet)


def _placed(study, status, realization: int, key: str, value, quiet: bool, what: str = "") -> None:
    """Warn of, or refuse (``key = value`` blamed), the unplaced nodes of ``status``."""
    failed, why = placement_failures(status)
    if not quiet and WARN_UNPLACED < failed <= study.solver.failure_budget:
        print(f"{study.name}: warning: {what}{failed:.0%} of the nodes of realisation {realization} cannot be placed "
              f"({why}); within solver.failure_budget = {study.solver.failure_budget:g}, so the run goes on "
              "and those nodes are NaN in its results", file=sys.stderr)
    refused = unplaced_error(status, study.solver.failure_budget, "solver.failure_budget",
                             f"{what}realisation {realization}")
    if refused:
        raise study_error(study.path, key, value, refused)


def run_preflight(study, output_dir, *, chunk_size: int | None = None, sample_rows=None, quiet: bool = False):
    """The ``preflight`` of ``uqdrape.ensemble.run_ensemble`` for a run of ``study`` into
    ``output_dir``: resources for the drapes still to write (a target run's round: also
    those its later rounds may add up to ``max_realizations``; a hierarchical run with its
    fixed twin: twice them), placement of the first."""
    later = (budget(study)[1] - study.realizations) * len(study.force_levels)
    twice = 2 if study.report.fixed_twin else 1

    def check(drapes: int, first: int, force: float) -> None:
        check_resources(study, output_dir, twice * (drapes + later), chunk_size)
        check_placement(study, first, force, sample_rows, quiet=quiet)
    return check


def validate_study(path):
    """Read a study file (``uqdrape.study.load_study``) and run the preflight a run of it
    would run: resources for the whole ensemble in its output folder, and the placement of
    its first realisation (a run to a target: for its budget, ``max_realizations``; twice
    with a fixed twin). Returns the Study; raises StudyError naming file and key."""
    study = load_study(path)
    why = at(study.output_dir).refused_with(None)  # as `uqdrape run` runs it: local worker processes
    if why:
        raise study_error(study.path, "output.directory", str(study.output_dir), why)
    drapes = budget(study)[1] * len(study.force_levels) * (2 if study.report.fixed_twin else 1)
    check_resources(study, study.output_dir, 0 if study.design is not None else drapes)
    check_placement(study)
    return study
