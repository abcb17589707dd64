#!/usr/bin/env python3
"""API latency and failover with separate worker processes on one database.

    cohortforge phantoms --family lv --count 20 --seed 1 --out phantoms/lv
    python3 scripts/worker_processes.py --cohortforge target/release/cohortforge \
        --phantoms phantoms/lv

Starts `cohortforge serve --workers 0` and two `cohortforge worker` processes on a fresh
SQLite file in a temporary directory (or, with --database postgres://..., on that
PostgreSQL database, which must be empty), uploads the phantoms, then:

1. times --requests sequential `GET /v1/jobs/{id}` with no job running (baseline);
2. queues --fits RSMP fits (default parameters), and times the same requests while both
   workers fit;
3. kills the worker running the oldest job with SIGKILL and reports the seconds until
   its job is queued again and until another worker has started it;
4. waits for every job, checks that each succeeded once with its own model, and prints
   the percentiles, their ratios to the baseline, and an excerpt of a worker's /metrics.
"""

import argparse
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path


def call(method, url, body=None, headers=None, raw=False):
    data, headers = None, dict(headers or {})
    if isinstance(body, (dict, list)):
        data = json.dumps(body).encode()
        headers["content-type"] = "application/json"
    elif body is not None:
        data = body
    request = urllib.request.Request(url, data=data, method=method, headers=headers)
    with urllib.request.urlopen(request, timeout=600) as response:
        payload = response.read()
        return payload if raw else json.loads(payload)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_ready(url):
    for _ in range(600):
        try:
            call("GET", f"{url}/readyz")
            return
        except OSError:
            time.sleep(0.1)
    sys.exit(f"{url} never became ready")


def percentiles(seconds):
    ms = sorted(1000 * s for s in seconds)
    pick = lambda q: ms[min(len(ms) - 1, int(q * len(ms)))]
    return {"p50_ms": round(pick(0.5), 2), "p99_ms": round(pick(0.99), 2),
            "max_ms": round(ms[-1], 2), "n": len(ms)}


def time_polls(base, job, n):
    out = []
    for _ in range(n):
        t = time.monotonic()
        call("GET", f"{base}/v1/jobs/{job}")
        out.append(time.monotonic() - t)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cohortforge", required=True, help="the binary")
    ap.add_argument("--phantoms", required=True, help="directory of OBJ phantoms")
    ap.add_argument("--fits", type=int, default=4)
    ap.add_argument("--requests", type=int, default=2000)
    ap.add_argument("--lease-seconds", type=int, default=5)
    ap.add_argument("--database", help="postgres:// URL of an empty database (default: a new SQLite file)")
    args = ap.parse_args()

    tmp = tempfile.mkdtemp(prefix="cohortforge-workers.")
    database = args.database or f"sqlite://{tmp}/cf.db"
    env = dict(os.environ, COHORTFORGE_LOG="warn", COHORTFORGE_DATABASE=database,
               COHORTFORGE_LEASE_SECONDS=str(args.lease_seconds))
    api_port = free_port()
    base = f"http://127.0.0.1:{api_port}"
    processes = [subprocess.Popen([args.cohortforge, "serve", "--workers", "0", "--bind",
                                   f"127.0.0.1:{api_port}"], env=env)]
    wait_ready(base)
    workers = []
    for _ in range(2):
        port = free_port()
        p = subprocess.Popen([args.cohortforge, "worker", "--bind", f"127.0.0.1:{port}"], env=env)
        processes.append(p)
        workers.append((p, f"http://127.0.0.1:{port}"))
        wait_ready(workers[-1][1])
    try:
        dataset = call("POST", f"{base}/v1/datasets", {"name": "workers", "organ": "lv"})["id"]
        for f in sorted(Path(args.phantoms).glob("*.obj")):
            call("POST", f"{base}/v1/datasets/{dataset}/meshes?name={f.stem}", f.read_bytes(),
                 {"content-type": "model/obj"})
        probe = call("POST", f"{base}/v1/jobs", {"dataset_id": dataset, "model_type": "rsmp",
                                                 "seed": 99, "holdout_fraction": 0.2})["id"]
        call("POST", f"{base}/v1/jobs/{probe}/cancel")
        while call("GET", f"{base}/v1/jobs/{probe}")["status"] in ("queued", "running"):
            time.sleep(0.1)
        idle = time_polls(base, probe, args.requests)

        jobs = [call("POST", f"{base}/v1/jobs", {"dataset_id": dataset, "model_type": "rsmp",
                                                 "seed": s, "holdout_fraction": 0.2})["id"]
                for s in range(args.fits)]
        while call("GET", f"{base}/v1/jobs?status=running")["total"] < 2:
            time.sleep(0.05)
        busy = time_polls(base, probe, args.requests)
        busy_running = call("GET", f"{base}/v1/jobs?status=running")["total"]

        # Kill the first worker; its job is the running one that the survivor is not on.
        victim, survivor = workers[0], workers[1]
        running_before = {j["id"] for j in call("GET", f"{base}/v1/jobs?status=running")["items"]}
        victim[0].send_signal(signal.SIGKILL)
        victim[0].wait()
        killed = time.monotonic()
        requeued = restarted = None
        orphan = None
        while restarted is None and time.monotonic() - killed < 600:
            for j in jobs:
                job = call("GET", f"{base}/v1/jobs/{j}")
                if j in running_before and (job["status"] == "queued" or job["attempts"] == 2):
                    orphan = j
                    requeued = requeued or time.monotonic() - killed
                    if job["status"] == "running" and job["attempts"] == 2:
                        restarted = time.monotonic() - killed
            time.sleep(0.05)
        for j in jobs:
            while (job := call("GET", f"{base}/v1/jobs/{j}"))["status"] in ("queued", "running"):
                time.sleep(0.5)
            if job["status"] != "succeeded":
                sys.exit(f"job {j} {job['status']}: {job.get('error')}")
        models = call("GET", f"{base}/v1/models?limit=100")
        metrics = call("GET", f"{survivor[1]}/metrics", raw=True).decode()
        excerpt = [line for line in metrics.splitlines()
                   if line.startswith(("cohortforge_job_run_seconds_count", "cohortforge_job_run_seconds_sum",
                                       "cohortforge_fit_stage_seconds_sum"))]
        idle_p, busy_p = percentiles(idle), percentiles(busy)
        print(json.dumps({
            "get_job_idle": idle_p,
            "get_job_while_two_workers_fit": dict(busy_p, jobs_running=busy_running),
            "p99_ratio_busy_to_idle": round(busy_p["p99_ms"] / idle_p["p99_ms"], 2),
            "killed_job": orphan,
            "requeued_after_kill_s": requeued and round(requeued, 2),
            "restarted_after_kill_s": restarted and round(restarted, 2),
            "lease_seconds": args.lease_seconds,
            "jobs_succeeded": len(jobs),
            "models_stored": models["total"],
            "worker_metrics_excerpt": excerpt,
        }, indent=2))
    finally:
        for p in processes:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in processes:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


if __name__ == "__main__":
    main()
