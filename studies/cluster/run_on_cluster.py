"""Run a study on a batch cluster through dask-jobqueue (SLURM or PBS), or on a local
dask cluster to try the same script on one machine.

Started on the cluster's login node (it submits the worker jobs itself and waits for the
run), in an environment with uqdrape installed and, for slurm / pbs, dask-jobqueue
(``pip install dask-jobqueue``)::

    python studies/cluster/run_on_cluster.py studies/nosecone-zero-angle.toml \
        --cluster slurm --jobs 4 --cores 32 --memory 128GB --walltime 04:00:00 \
        --account myproject --out /scratch/$USER/nosecone

Each worker job is one node's ``--cores`` single-threaded worker processes (a drape is
one Python thread; a chunk is one task). ``--out`` must be a folder every worker job can
write (the cluster's shared /scratch), or a store URL the workers reach (s3://..., with
the credentials in the job's environment). The run resumes like any other: submit the
same command again after a wall-time kill. ``--cluster local`` starts
``distributed.LocalCluster`` with ``--cores`` processes instead (tested here).
"""

from __future__ import annotations

import argparse
import sys


def make_cluster(args):
    """The dask cluster of ``--cluster``: jobs of ``--cores`` worker processes each."""
    if args.cluster == "local":
        from distributed import LocalCluster

        return LocalCluster(n_workers=args.cores, threads_per_worker=1, processes=True)
    import dask_jobqueue

    kind = {"slurm": dask_jobqueue.SLURMCluster, "pbs": dask_jobqueue.PBSCluster}[args.cluster]
    cluster = kind(cores=args.cores, processes=args.cores, memory=args.memory, walltime=args.walltime,
                   account=args.account, job_name="uqdrape",
                   # the worker jobs inherit no shell: bring uqdrape's environment
                   job_script_prologue=[f"source {args.venv}/bin/activate"] if args.venv else [])
    cluster.scale(jobs=args.jobs)
    return cluster


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("study", help="study file (TOML)")
    p.add_argument("--cluster", choices=("slurm", "pbs", "local"), default="slurm")
    p.add_argument("--jobs", type=int, default=2, help="worker jobs to submit (slurm, pbs)")
    p.add_argument("--cores", type=int, default=32, help="worker processes per job (local: in all)")
    p.add_argument("--memory", default="64GB", help="memory per job")
    p.add_argument("--walltime", default="02:00:00", help="wall time per worker job")
    p.add_argument("--account", help="the batch account (project) to charge")
    p.add_argument("--venv", help="virtual environment the worker jobs activate")
    p.add_argument("--out", help="output folder or store URL (default: the study's [output] directory)")
    args = p.parse_args(argv)

    from uqdrape.cli import main as uqdrape

    with make_cluster(args) as cluster:
        print(f"dask dashboard: {cluster.dashboard_link}", file=sys.stderr)
        return uqdrape(["run", args.study, "--scheduler", cluster.scheduler_address]
                       + (["--out", args.out] if args.out else []))


if __name__ == "__main__":
    sys.exit(main())
