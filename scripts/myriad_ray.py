#!/usr/bin/env python3
"""Runs a planned Myriad build on Ray: the parts as Ray tasks, then the merge.

Inputs, the plan, the parts and the dataset may be on a filesystem every node shares (plain
paths) or on S3-compatible storage (s3://BUCKET/KEY; --endpoint-url for servers other than
AWS; credentials as boto3 reads them: AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY, passed on to
the workers).

    # plan (on this machine; S3 inputs are copied to --stage first, the plan names those copies)
    python scripts/myriad_ray.py plan s3://scans/a.laz s3://scans/b.laz -o s3://scans/city.json \\
        --parts 16 -- --memory 8GB
    # the parts as tasks, then the merge
    python scripts/myriad_ray.py run s3://scans/city.json --parts-dir s3://scans/city-parts/ \\
        -o s3://scans/city.myr --address auto

A part's task copies the S3 inputs its cells need (`myriad convert --plan ... --list-inputs`) to
the same --stage path on its node, builds the part there and uploads it; the merge's task
downloads the parts, merges (their pages copied into the dataset) and uploads it. With paths on
a shared filesystem nothing is copied: the dataset links the parts' files where they are. A failed part fails the run (exit 1, naming it) and nothing is merged.

Needs `ray` (and `boto3` for S3) from PyPI, and `myriad` on every node (--myriad).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

DEFAULT_STAGE = os.path.join(tempfile.gettempdir(), "myriad-ray")


def is_s3(path):
    return path.startswith("s3://")


def split_s3(url):
    bucket, _, key = url[len("s3://"):].partition("/")
    if not bucket:
        raise SystemExit(f"error: {url}: expected s3://BUCKET/KEY")
    return bucket, key


def s3_client(endpoint):
    import boto3

    return boto3.client("s3", endpoint_url=endpoint)


def staged(stage, url):
    """Where an S3 object is copied on a node: the same path on every node."""
    bucket, key = split_s3(url)
    return os.path.join(stage, "s3", bucket, key)


def download(endpoint, url, dest):
    """Copies an S3 object whole to dest, unless it is there whole already."""
    stage_ranges(endpoint, url, dest, [(0, None)])
    return dest


def stage_ranges(endpoint, url, dest, ranges):
    """Copies the byte ranges `ranges` ((start, end), end excluded or None: to the end) of an S3
    object into dest, a file of the object's size whose other bytes are not there (a sparse
    file); `dest.ranges` lists what is, so that the tasks on one node add to one copy, and
    only what is missing is fetched. Held under `dest.lock` while it changes. Returns the bytes
    fetched."""
    import fcntl

    s3 = s3_client(endpoint)
    bucket, key = split_s3(url)
    size = s3.head_object(Bucket=bucket, Key=key)["ContentLength"]
    os.makedirs(os.path.dirname(dest), exist_ok=True)
    fetched = 0
    with open(dest + ".lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            with open(dest + ".ranges") as f:
                have = [tuple(r) for r in json.load(f)]
        except (OSError, ValueError):
            have = []
        if not os.path.exists(dest) or os.path.getsize(dest) != size:
            with open(dest, "wb") as f:
                f.truncate(size)
            have = []
        with open(dest, "r+b") as f:
            for start, end in ranges:
                end = size if end is None else min(end, size)
                missing = [(start, end)]
                for a, b in have:
                    missing = [
                        piece
                        for m0, m1 in missing
                        for piece in ((m0, min(m1, a)), (max(m0, b), m1))
                        if piece[0] < piece[1]
                    ]
                for m0, m1 in missing:
                    body = s3.get_object(Bucket=bucket, Key=key, Range=f"bytes={m0}-{m1 - 1}")
                    f.seek(m0)
                    got = 0
                    for piece in body["Body"].iter_chunks(1 << 20):
                        f.write(piece)
                        got += len(piece)
                    if got != m1 - m0:
                        raise RuntimeError(f"{url}: {got} bytes for the range {m0}-{m1}")
                    fetched += got
                    have.append((m0, m1))
            f.flush()
            os.fsync(f.fileno())
        with open(dest + ".ranges", "w") as f:
            json.dump(sorted(have), f)
        return fetched


def stage_part_inputs(endpoint, myriad, local_plan, index, urls):
    """The S3 inputs part `index` reads, staged where the plan names them: the LAZ inputs it
    reads some chunks of by their byte ranges (the header and chunk table first, then what
    `convert --list-ranges` asks for), the others whole. Returns the bytes fetched and the
    bytes of those inputs whole."""
    with open(local_plan) as f:
        plan = json.load(f)
    chunked = {plan["inputs"][c["input"]]["path"] for c in plan.get("chunked", [])}
    listed = run_myriad(
        myriad, ["convert", "--plan", local_plan, "--part", str(index), "--list-inputs"]
    ).splitlines()
    fetched = 0
    for path in listed:
        if path in urls and path in chunked:
            # The header (its size and the point data's place at byte 94 and 96), then the
            # chunk table, whose place is the 8 bytes where the point data start.
            fetched += stage_ranges(endpoint, urls[path], path, [(0, 375)])
            with open(path, "rb") as f:
                head = f.read(375)
                data_at = int.from_bytes(head[96:100], "little")
            fetched += stage_ranges(endpoint, urls[path], path, [(0, data_at + 8)])
            with open(path, "rb") as f:
                f.seek(data_at)
                table_at = int.from_bytes(f.read(8), "little", signed=True)
            if table_at > data_at:
                fetched += stage_ranges(endpoint, urls[path], path, [(table_at, None)])
            else:
                fetched += stage_ranges(endpoint, urls[path], path, [(0, None)])
    ranges = {}
    if any(p in urls and p in chunked for p in listed):
        out = run_myriad(
            myriad, ["convert", "--plan", local_plan, "--part", str(index), "--list-ranges"]
        )
        for line in out.splitlines():
            path, start, end = line.rsplit(" ", 2)
            ranges.setdefault(path, []).append((int(start), None if end == "end" else int(end)))
    whole = 0
    for path in listed:
        if path in urls:
            fetched += stage_ranges(endpoint, urls[path], path, ranges.get(path, [(0, None)]))
            whole += os.path.getsize(path)
    return fetched, whole


def upload(endpoint, path, url):
    bucket, key = split_s3(url)
    s3_client(endpoint).upload_file(path, bucket, key)


def join(base, name):
    return base.rstrip("/") + "/" + name


def fetch(endpoint, path, local_dir):
    """A local path for `path`: itself, or an S3 object copied into local_dir."""
    if not is_s3(path):
        return path
    return download(endpoint, path, os.path.join(local_dir, os.path.basename(path)))


def run_myriad(myriad, args):
    r = subprocess.run([myriad] + args, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"myriad {' '.join(args)}: {r.stderr.strip()}")
    return r.stdout


def build_part(index, plan, parts_dir, myriad, endpoint, stage):
    """One part: its S3 inputs staged, built, uploaded where the parts go. Runs as a Ray task."""
    work = os.path.join(stage, f"part-{index}-{os.getpid()}")
    os.makedirs(work, exist_ok=True)
    try:
        local_plan = fetch(endpoint, plan, work)
        with open(local_plan) as f:
            urls = json.load(f).get("staged_from_s3", {})
        fetched, whole = stage_part_inputs(endpoint, myriad, local_plan, index, urls)
        out = os.path.join(work, "parts") if is_s3(parts_dir) else parts_dir
        summary = json.loads(
            run_myriad(
                myriad,
                ["convert", "--plan", local_plan, "--part", str(index), "-o", out, "--json"],
            )
        )
        summary["staged_bytes"] = fetched
        summary["inputs_bytes"] = whole
        if is_s3(parts_dir):
            # The dataset first, the tops last: a part is complete when its tops are there.
            for name in (f"part-{index}.myr", f"part-{index}.tops"):
                if os.path.exists(os.path.join(out, name)):
                    upload(endpoint, os.path.join(out, name), join(parts_dir, name))
        return summary
    finally:
        shutil.rmtree(work, ignore_errors=True)


def merge(plan, parts_dir, output, parts, myriad, endpoint, stage):
    """The merge: parts downloaded where they are on S3 (their pages then copied into the
    dataset), the dataset uploaded. A Ray task."""
    work = os.path.join(stage, f"merge-{os.getpid()}")
    os.makedirs(work, exist_ok=True)
    try:
        local_plan = fetch(endpoint, plan, work)
        local_parts = parts_dir
        if is_s3(parts_dir):
            from botocore.exceptions import ClientError

            local_parts = os.path.join(work, "parts")
            for i in range(parts):
                for name in (f"part-{i}.tops", f"part-{i}.myr"):
                    try:
                        download(endpoint, join(parts_dir, name), os.path.join(local_parts, name))
                    except ClientError:
                        continue  # merge names a missing part; an empty part has no .myr
        out = os.path.join(work, os.path.basename(output)) if is_s3(output) else output
        # On a shared filesystem the dataset links the parts where they are; staged ones are
        # removed with this folder, so their pages are copied into the dataset.
        whole = ["--single-file"] if is_s3(parts_dir) or is_s3(output) else []
        summary = json.loads(
            run_myriad(
                myriad,
                ["merge", local_plan, local_parts, "-o", out, "--force", "--json", *whole],
            )
        )
        if is_s3(output):
            upload(endpoint, out, output)
        return summary
    finally:
        shutil.rmtree(work, ignore_errors=True)


def cmd_plan(a):
    """`myriad plan` on this machine; S3 inputs copied to the stage, the plan names the copies
    and keeps each one's URL (`staged_from_s3`, a field the plan's id does not cover), so that a
    part's task copies what it needs."""
    work = tempfile.mkdtemp(prefix="myriad-ray-plan-")
    try:
        local = []
        urls = {}
        for i in a.inputs:
            if is_s3(i):
                path = download(a.endpoint_url, i, staged(a.stage, i))
                urls[path] = i
                local.append(path)
            else:
                local.append(os.path.abspath(i))
        out = os.path.join(work, "plan.json") if is_s3(a.output) else a.output
        subprocess.run(
            [a.myriad, "plan", *local, "-o", out, "--parts", str(a.parts), "--force", *a.rest],
            check=True,
        )
        if urls:
            with open(out) as f:
                plan = json.load(f)
            plan["staged_from_s3"] = urls
            tmp = out + ".partial"
            with open(tmp, "w") as f:
                json.dump(plan, f, indent=2)
            os.replace(tmp, out)
        if is_s3(a.output):
            upload(a.endpoint_url, out, a.output)
        print(a.output)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def last_line(e):
    """The last line of a task's error: the cause, without Ray's traceback."""
    lines = str(getattr(e, "cause", e)).strip().splitlines()
    return lines[-1] if lines else str(e)


def cmd_run(a):
    host, _, port = (a.address or "").rpartition(":")
    if host in ("127.0.0.1", "localhost", "::1"):
        # Ray replaces a loopback address by this machine's outward one unless told not to (a
        # cluster bound to 127.0.0.1 is then never reached).
        os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    import ray

    work = tempfile.mkdtemp(prefix="myriad-ray-run-")
    try:
        with open(fetch(a.endpoint_url, a.plan, work)) as f:
            parts = len(json.load(f)["parts"])
    finally:
        shutil.rmtree(work, ignore_errors=True)
    env = {k: os.environ[k] for k in ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY",
                                      "AWS_SESSION_TOKEN", "AWS_DEFAULT_REGION")
           if k in os.environ}
    if a.address and a.address != "auto":
        # Ray waits for an unreachable cluster without end: say so at once instead.
        import socket

        try:
            socket.create_connection((host, int(port)), timeout=10).close()
        except (OSError, ValueError) as e:
            print(f"error: Ray cluster {a.address}: {e}", file=sys.stderr)
            return 1
    ray.init(address=a.address, runtime_env={"env_vars": env} if env else None,
             log_to_driver=False)
    part_task = ray.remote(num_cpus=a.part_cpus, max_retries=a.retries)(build_part)
    merge_task = ray.remote(num_cpus=a.part_cpus, max_retries=a.retries)(merge)
    args = (a.plan, a.parts_dir, a.myriad, a.endpoint_url, a.stage)
    refs = {part_task.remote(i, *args): i for i in range(parts)}
    failed = []
    for ref, i in refs.items():
        try:
            s = ray.get(ref)
            print(
                f"part {i}: {s['points']} points, {s['seconds']:.2f} s, fetched "
                f"{s.get('staged_bytes', 0)} of {s.get('inputs_bytes', 0)} bytes of its S3 inputs"
            )
        except Exception as e:  # a task's error, raised here
            failed.append(f"part {i}: {last_line(e)}")
    if failed:
        print(f"error: {a.output}: not merged: " + "; ".join(failed), file=sys.stderr)
        return 1
    try:
        s = ray.get(merge_task.remote(a.plan, a.parts_dir, a.output, parts, a.myriad,
                                      a.endpoint_url, a.stage))
    except Exception as e:
        print(f"error: {a.output}: merge failed: {last_line(e)}", file=sys.stderr)
        return 1
    print(f"merged {a.output}: {s['points']} points, {s['nodes']} nodes, {s['seconds']:.2f} s")
    return 0


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--endpoint-url", help="S3-compatible server, e.g. http://127.0.0.1:8333")
    p.add_argument("--myriad", default="myriad", help="the myriad program on every node")
    p.add_argument("--stage", default=DEFAULT_STAGE,
                   help=f"local folder for S3 copies on every node [{DEFAULT_STAGE}]")
    sub = p.add_subparsers(dest="cmd", required=True)
    pl = sub.add_parser("plan", help="myriad plan, with inputs on S3 or a shared filesystem")
    pl.add_argument("inputs", nargs="+")
    pl.add_argument("-o", "--output", required=True)
    pl.add_argument("--parts", type=int, required=True)
    pl.epilog = "More `myriad plan` options after --, e.g. -- --memory 8GB --capacity 20000"
    r = sub.add_parser("run", help="the parts as Ray tasks, then the merge")
    r.add_argument("plan")
    r.add_argument("--parts-dir", required=True)
    r.add_argument("-o", "--output", required=True)
    r.add_argument("--address", default=None,
                   help="Ray cluster (host:port or auto) [default: a local one for this run]")
    r.add_argument("--part-cpus", type=float, default=1, help="CPUs a part's task asks for")
    r.add_argument("--retries", type=int, default=0, help="retries of a failed task")
    argv = sys.argv[1:]
    # After `--`: more `myriad plan` options, passed as they are.
    rest = argv[argv.index("--") + 1:] if "--" in argv else []
    a = p.parse_args(argv[: len(argv) - len(rest) - 1] if "--" in argv else argv)
    a.rest = rest
    if a.cmd == "plan":
        cmd_plan(a)
        return 0
    return cmd_run(a)


if __name__ == "__main__":
    sys.exit(main())
