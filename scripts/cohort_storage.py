#!/usr/bin/env python3
"""What a large cohort costs a running service: time from request to stored, database
growth, and download times of stored members.

    cohortforge serve --database /tmp/cf.db &
    cohortforge phantoms --family lv --count 10 --seed 1 --out phantoms/lv
    python3 scripts/cohort_storage.py --base-url http://127.0.0.1:8080 \
        --database /tmp/cf.db --phantoms phantoms/lv --size 10000

Fits RSMP on the phantoms (80% for training), asks for a cohort of --size members with
`Prefer: respond-async`, polls it, then reports the seconds from request to `succeeded`, the
growth of the database files (main file and write-ahead log), and the median time of one
member download (OBJ) and of the whole archive (STL).
"""

import argparse
import json
import os
import statistics
import sys
import time
import urllib.request
from pathlib import Path


def call(method, url, body=None, headers=None, raw=False):
    data = None
    headers = dict(headers or {})
    if isinstance(body, (dict, list)):
        data = json.dumps(body).encode()
        headers["content-type"] = "application/json"
    elif body is not None:
        data = body
    request = urllib.request.Request(url, data=data, method=method, headers=headers)
    with urllib.request.urlopen(request, timeout=600) as response:
        payload = response.read()
        return payload if raw else json.loads(payload)


def database_bytes(path):
    return sum(os.path.getsize(p) for p in (path, path + "-wal") if os.path.exists(p))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base-url", required=True)
    ap.add_argument("--database", required=True, help="the server's SQLite file")
    ap.add_argument("--phantoms", required=True, help="directory of OBJ phantoms")
    ap.add_argument("--size", type=int, default=10000)
    ap.add_argument("--downloads", type=int, default=50)
    args = ap.parse_args()
    base = args.base_url.rstrip("/")

    dataset = call("POST", f"{base}/v1/datasets", {"name": "storage", "organ": "lv"})["id"]
    for f in sorted(Path(args.phantoms).glob("*.obj")):
        call("POST", f"{base}/v1/datasets/{dataset}/meshes?name={f.stem}", f.read_bytes(),
             {"content-type": "model/obj"})
    job = call("POST", f"{base}/v1/jobs", {"dataset_id": dataset, "model_type": "rsmp", "seed": 1})
    while job["status"] in ("queued", "running"):
        time.sleep(1)
        job = call("GET", f"{base}/v1/jobs/{job['id']}")
    if job["status"] != "succeeded":
        sys.exit(f"fit {job['status']}: {job.get('error')}")
    model = job["model_id"]

    before = database_bytes(args.database)
    started = time.monotonic()
    cohort = call("POST", f"{base}/v1/models/{model}/cohorts", {"size": args.size, "seed": 7},
                  {"prefer": "respond-async"})
    while cohort["status"] in ("queued", "running"):
        time.sleep(0.2)
        cohort = call("GET", f"{base}/v1/cohorts/{cohort['id']}")
    seconds = time.monotonic() - started
    if cohort["status"] != "succeeded":
        sys.exit(f"cohort {cohort['status']}: {cohort.get('error')}")
    grown = database_bytes(args.database) - before

    member = []
    for i in range(args.downloads):
        t = time.monotonic()
        index = (i * 7919) % args.size
        call("GET", f"{base}/v1/cohorts/{cohort['id']}/members/{index}/file?format=obj", raw=True)
        member.append(time.monotonic() - t)
    t = time.monotonic()
    archive = call("GET", f"{base}/v1/cohorts/{cohort['id']}/archive?format=stl", raw=True)
    archive_s = time.monotonic() - t

    print(json.dumps({
        "members": cohort["member_count"],
        "request_to_stored_s": round(seconds, 2),
        "members_per_s": round(cohort["member_count"] / seconds),
        "database_growth_mb": round(grown / 1e6, 1),
        "bytes_per_member": round(grown / cohort["member_count"]),
        "member_download_median_ms": round(1000 * statistics.median(member), 1),
        "archive_stl_s": round(archive_s, 2),
        "archive_mb": round(len(archive) / 1e6, 1),
    }, indent=2))


if __name__ == "__main__":
    main()
