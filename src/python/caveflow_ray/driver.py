"""Run a caveflow study on a Ray cluster: one Ray task per variant.

The study's expansion lives in Rust only: the driver asks ``caveflow study --plan STUDY``
for the variants (name, hash, ...), skips those already complete (``OUT/variants/<name>/
_SUCCESS`` holds the variant's hash), and submits one task per remaining variant, each
running ``caveflow study STUDY --variant NAME --out OUT --threads T`` (T: the task's CPUs,
``--task-cpus``) on whichever node Ray picks. The
tasks write the layout of the local runner (``OUT/dataset/<table>/study=<s>/scenario=<v>/``,
``OUT/variants/<v>/``), so ``OUT`` must be on a file system every node sees, and the
study's files and the binary must be at the same paths on every node. When every task is
done the driver runs ``caveflow study STUDY --out OUT --summary-only``, which writes
``summary.parquet`` from the complete variants and runs none.

Failures:

* a task whose worker dies (killed, node lost) is retried by Ray (``max_retries``);
* a caveflow that exits with a code other than 0 and 1 (killed by a signal, an I/O error)
  raises :class:`TaskDied`, which is retried too (``retry_exceptions``);
* a caveflow that exits 1 (invalid input: a bad table of that variant, a scene where the
  method fails) is not retried: the variant is reported at the end, and the driver exits 1.

Each attempt appends its command, exit code and caveflow's output to
``OUT/ray/<variant>.log`` (one ``attempt`` header per attempt).

Exit codes: 0 every variant complete; 1 some variant had invalid input or is not
complete; 2 any other error (a plan that cannot be read, a task out of retries).

Fault injection for tests: ``--kill-once NAME`` makes the first attempt of variant NAME
start caveflow, SIGKILL it after ``--kill-after`` seconds, then SIGKILL its own Ray worker
(a marker ``OUT/ray/<NAME>.killed`` records that it did); Ray retries the task, and the
retry removes what the killed writer left (``analysis::study``, "Killed at any point").
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import ray
from ray import cloudpickle


# caveflow ended with neither success nor invalid input (another exit code, a signal): the
# task raises this and Ray retries it. A builtin, so that it is the same class in the driver
# and in every worker however this module reaches them (pickled by value, below).
TaskDied = ChildProcessError


def plan(caveflow: str, study: Path) -> dict:
    """The expanded study, as ``caveflow study --plan`` prints it."""
    r = subprocess.run([caveflow, "study", "--plan", str(study)], capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        raise SystemExit(r.returncode if r.returncode in (1, 2) else 2)
    return json.loads(r.stdout)


def is_complete(out: Path, variant: dict) -> bool:
    """Whether the variant's ``_SUCCESS`` holds its hash (as ``Layout::is_complete``)."""
    try:
        return (out / "variants" / variant["name"] / "_SUCCESS").read_text().strip() == variant["hash"]
    except OSError:
        return False


def run_variant(caveflow: str, study: str, out: str, name: str, threads: int, kill_once: bool,
                kill_after: float) -> dict:
    """One attempt at one variant (the body of the Ray task), on ``threads`` threads (the
    task's CPUs). Returns ``{"name", "code", "seconds", "host"}`` for exit 0 and 1; raises
    :class:`TaskDied` for any other exit."""
    logs = Path(out) / "ray"
    logs.mkdir(parents=True, exist_ok=True)
    log = logs / f"{name}.log"
    cmd = [caveflow, "study", study, "--variant", name, "--out", out, "--threads", str(threads)]
    t0 = time.monotonic()
    with open(log, "a") as f:
        f.write(f"attempt on {socket.gethostname()} pid {os.getpid()}: {' '.join(cmd)}\n")
        f.flush()
        child = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT)
        marker = logs / f"{name}.killed"
        if kill_once and not marker.exists():
            time.sleep(kill_after)
            child.kill()
            child.wait()
            marker.write_text(f"{os.getpid()}\n")
            f.write("fault injection: caveflow and this worker killed (SIGKILL)\n")
            f.flush()
            os.kill(os.getpid(), signal.SIGKILL)
        code = child.wait()
        f.write(f"exit {code}\n")
    seconds = time.monotonic() - t0
    if code not in (0, 1):
        raise TaskDied(f"variant {name}: caveflow exited with {code} (see {log})")
    return {"name": name, "code": code, "seconds": seconds, "host": socket.gethostname()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="caveflow-ray", description=__doc__.split("\n\n")[0])
    ap.add_argument("study", type=Path, help="the study file (TOML)")
    ap.add_argument("--out", type=Path, default=Path("study"), help="output directory (default: study)")
    ap.add_argument("--caveflow", default=os.environ.get("CAVEFLOW_BIN", "caveflow"),
                    help="the caveflow binary (default: $CAVEFLOW_BIN, else caveflow on PATH)")
    ap.add_argument("--address", default=os.environ.get("RAY_ADDRESS"),
                    help="a Ray cluster to join (default: $RAY_ADDRESS, else a local one on 127.0.0.1)")
    ap.add_argument("--num-cpus", type=int, default=2, help="CPUs of the local cluster (default 2)")
    ap.add_argument("--task-cpus", type=float, default=1.0,
                    help="CPUs each task reserves, and its caveflow's --threads (at least 1; default 1)")
    ap.add_argument("--max-retries", type=int, default=3, help="retries of a task that dies (default 3)")
    ap.add_argument("--kill-once", metavar="NAME", help="fault injection (tests): kill the first attempt of NAME")
    ap.add_argument("--kill-after", type=float, default=0.2, help="seconds before --kill-once kills (default 0.2)")
    a = ap.parse_args(argv)

    caveflow = a.caveflow
    if os.sep in caveflow:
        caveflow = str(Path(caveflow).resolve())
    study, out = a.study.resolve(), a.out.resolve()
    p = plan(caveflow, study)
    todo = [v for v in p["variants"] if not is_complete(out, v)]
    print(f"study {p['study']}: {len(p['variants'])} variant(s), {len(todo)} to run on Ray", flush=True)

    failed: list[tuple[str, str]] = []
    invalid: list[str] = []
    if todo:
        t0 = time.monotonic()
        if a.address:
            ray.init(address=a.address, log_to_driver=False)
        else:
            ray.init(num_cpus=a.num_cpus, include_dashboard=False, _node_ip_address="127.0.0.1",
                     log_to_driver=False)
        # Ship this module's functions by value: the workers need not have it installed.
        if run_variant.__module__ != "__main__":
            cloudpickle.register_pickle_by_value(sys.modules[run_variant.__module__])
        task = ray.remote(num_cpus=a.task_cpus, max_retries=a.max_retries,
                          retry_exceptions=[TaskDied])(run_variant)
        t1 = time.monotonic()
        threads = max(1, int(a.task_cpus))
        refs = {task.remote(caveflow, str(study), str(out), v["name"], threads, v["name"] == a.kill_once,
                            a.kill_after): v["name"] for v in todo}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            name = refs[done[0]]
            try:
                r = ray.get(done[0])
            except Exception as e:  # out of retries: the worker kept dying, or TaskDied
                failed.append((name, (str(e).strip().splitlines() or [type(e).__name__])[-1]))
                print(f"{name}: failed", flush=True)
                continue
            if r["code"] == 1:
                invalid.append(name)
                print(f"{name}: invalid input, not retried (see {out / 'ray' / (name + '.log')})", flush=True)
            else:
                print(f"{name}: done in {r['seconds']:.2f} s on {r['host']}", flush=True)
        t2 = time.monotonic()
        ray.shutdown()
        print(f"{len(todo)} task(s) in {t2 - t1:.2f} s; Ray up in {t1 - t0:.2f} s, down in "
              f"{time.monotonic() - t2:.2f} s", flush=True)

    s = subprocess.run([caveflow, "study", str(study), "--out", str(out), "--summary-only"])
    for name in invalid:
        print(f"error: variant {name}: invalid input (exit 1), see {out / 'ray' / (name + '.log')}", file=sys.stderr)
    for name, why in failed:
        print(f"error: variant {name}: {why}", file=sys.stderr)
    if failed:
        return 2
    if invalid or s.returncode != 0:
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
