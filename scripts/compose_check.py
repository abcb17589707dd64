#!/usr/bin/env python3
"""Runs the services of docker/compose.yml as plain processes against a PostgreSQL.

    eval "$(scripts/postgres_throwaway.sh start)"
    python3 scripts/compose_check.py --cohortforge target/debug/cohortforge \
        --postgres "$COHORTFORGE_TEST_POSTGRES"

Checks what the compose file says without a container engine: each cohortforge service's
`command` and `environment` (anchors, merge keys and ${VAR:-default} / ${VAR:?message}
interpolation resolved as compose does) start the same binary, `deploy.replicas` worker
processes included. Only what containers change is replaced: the `postgres` service is the
given server (its POSTGRES_USER, POSTGRES_PASSWORD and POSTGRES_DB are created there, so the
services' database URL works as written once its host is pointed at that server), and
listeners keep their interface but get free ports (every container has its own). Then:

- the API answers /readyz, refuses /v1 without the token and accepts it with;
- every worker answers /healthz, /readyz and /metrics;
- an RSMP fit queued through the API is run by one of the workers (none runs in the API);
- the API's /metrics counts the request by its route.

Needs PyYAML and psql. Exits non-zero with the reason when a check fails.
"""

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import urllib.error
from pathlib import Path
from urllib.parse import urlsplit

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from worker_processes import call, free_port  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
VARIABLE = re.compile(r"\$\{(\w+)(?:(:-|:\?)([^}]*))?\}")


def interpolate(text, env):
    """${VAR}, ${VAR:-default} and ${VAR:?message} as compose resolves them."""
    def one(m):
        name, op, arg = m.group(1), m.group(2), m.group(3) or ""
        value = env.get(name, "")
        if op == ":?" and not value:
            sys.exit(f"compose refuses to start: {name}: {arg}")
        return value if value or op != ":-" else arg
    return VARIABLE.sub(one, text)


def resolve(node, env):
    """Interpolates every string of the parsed file, as compose does after parsing."""
    if isinstance(node, dict):
        return {k: resolve(v, env) for k, v in node.items()}
    if isinstance(node, list):
        return [resolve(v, env) for v in node]
    return interpolate(node, env) if isinstance(node, str) else node


def fail(message):
    sys.exit(f"FAIL {message}")


def psql(admin_url, sql):
    subprocess.run(["psql", "-v", "ON_ERROR_STOP=1", "-q", admin_url, "-c", sql], check=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cohortforge", required=True, help="the binary the image would contain")
    ap.add_argument("--postgres", required=True, help="postgres://SUPERUSER@HOST:PORT of a server to use")
    ap.add_argument("--compose", default=str(REPO / "docker" / "compose.yml"))
    args = ap.parse_args()

    env = dict(os.environ)
    env.setdefault("COHORTFORGE_ADMIN_TOKEN", "compose-check-" + os.urandom(8).hex())
    compose = resolve(yaml.safe_load(Path(args.compose).read_text()), env)
    services = compose["services"]
    db = services["postgres"]["environment"]
    server = urlsplit(args.postgres)
    admin = f"postgres://{server.netloc}/postgres"
    psql(admin, f"DROP DATABASE IF EXISTS {db['POSTGRES_DB']}")
    psql(admin, f"DROP ROLE IF EXISTS {db['POSTGRES_USER']}")
    psql(admin, f"CREATE ROLE {db['POSTGRES_USER']} LOGIN PASSWORD '{db['POSTGRES_PASSWORD']}'")
    psql(admin, f"CREATE DATABASE {db['POSTGRES_DB']} OWNER {db['POSTGRES_USER']}")

    tmp = Path(tempfile.mkdtemp(prefix="cohortforge-compose."))
    processes, listeners = [], {}
    try:
        for name, service in services.items():
            if "build" not in service:
                continue
            for replica in range(service.get("deploy", {}).get("replicas", 1)):
                # A variable without a value is passed through from the host, or left unset.
                senv = {k: str(v) if v is not None else env.get(k) for k, v in
                        service.get("environment", {}).items()}
                senv = {k: v for k, v in senv.items() if v is not None}
                senv["COHORTFORGE_DATABASE"] = senv["COHORTFORGE_DATABASE"].replace(
                    "@postgres:5432/", f"@{server.hostname}:{server.port}/")
                for key in ("COHORTFORGE_BIND", "COHORTFORGE_WORKER_BIND"):
                    if key in senv:
                        port = free_port()
                        senv[key] = re.sub(r":\d+$", f":{port}", senv[key])
                        listeners[f"{name}-{replica + 1}"] = f"http://127.0.0.1:{port}"
                log = open(tmp / f"{name}-{replica + 1}.log", "w")
                processes.append(subprocess.Popen([args.cohortforge, *service["command"]], cwd=tmp,
                                                  env={**os.environ, **senv}, stdout=log, stderr=log))
        for (name, url), p in zip(listeners.items(), processes):
            for _ in range(600):
                if p.poll() is not None:
                    fail(f"{name} exited: {(tmp / f'{name}.log').read_text().strip()[-2000:]}")
                try:
                    call("GET", f"{url}/readyz", raw=True)
                    break
                except OSError:
                    time.sleep(0.1)
            else:
                fail(f"{name} never became ready at {url}")
            print(f"ok {name} ready at {url}")
        check_flow(listeners, env["COHORTFORGE_ADMIN_TOKEN"], args.cohortforge, tmp)
    finally:
        for p in processes:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in processes:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def check_flow(listeners, token, binary, tmp):
    api = listeners.get("api-1") or fail("no api service with a listener")
    workers = [url for name, url in listeners.items() if name.startswith("worker-")]
    if len(workers) != 2:
        fail(f"expected two worker replicas, found {len(workers)}")
    try:
        call("GET", f"{api}/v1/jobs")
        fail("the API answered /v1 without a token")
    except urllib.error.HTTPError as e:
        if e.code != 401:
            fail(f"/v1 without a token answered {e.code}, not 401")
    print("ok api refuses /v1 without the token")
    auth = {"authorization": f"Bearer {token}"}
    for url in workers:
        for probe in ("healthz", "readyz"):
            call("GET", f"{url}/{probe}", raw=True)
    print("ok workers answer their probes")

    phantoms = tmp / "phantoms"
    subprocess.run([binary, "phantoms", "--family", "lv", "--count", "8", "--seed", "1",
                    "--out", str(phantoms)], check=True, stdout=subprocess.DEVNULL)
    dataset = call("POST", f"{api}/v1/datasets", {"name": "compose", "organ": "lv"}, auth)["id"]
    for f in sorted(phantoms.glob("*.obj")):
        call("POST", f"{api}/v1/datasets/{dataset}/meshes?name={f.stem}", f.read_bytes(),
             {**auth, "content-type": "model/obj"})
    job = call("POST", f"{api}/v1/jobs", {"dataset_id": dataset, "model_type": "rsmp", "seed": 1,
                                          "params": {"multistart": False, "cpd_max_iterations": 50}},
               auth)["id"]
    deadline = time.monotonic() + 600
    while (status := call("GET", f"{api}/v1/jobs/{job}", headers=auth))["status"] in ("queued", "running"):
        if time.monotonic() > deadline:
            fail("the fit did not finish within 10 minutes")
        time.sleep(0.5)
    if status["status"] != "succeeded":
        fail(f"the fit ended {status['status']}: {status.get('error')}")
    runs = [run_count(call("GET", f"{url}/metrics", raw=True).decode()) for url in workers]
    if sorted(runs) != [0, 1]:
        fail(f"expected exactly one worker to have run the fit, runs per worker: {runs}")
    print(f"ok the fit ran on worker {runs.index(1) + 1} of 2 and succeeded")
    text = call("GET", f"{api}/metrics", raw=True).decode()
    if 'route="/v1/jobs/{id}"' not in text:
        fail("the API's /metrics has no request duration for /v1/jobs/{id}")
    print("ok the API's /metrics counts requests by route")


def run_count(metrics):
    return sum(int(float(line.rsplit(" ", 1)[1])) for line in metrics.splitlines()
               if line.startswith("cohortforge_job_run_seconds_count") and 'outcome="succeeded"' in line)


if __name__ == "__main__":
    main()
