#!/usr/bin/env python3
"""Where `myriad convert` spends its CPU, phase by phase: a `perf record` of one build, its
samples placed in the phases the build's --json summary reports, grouped by what they do.

    scripts/profile-convert.py target/release/myriad SCAN.laz [convert options...]

Needs perf (Debian: linux-perf) and kernel.perf_event_paranoid <= 2. Prints, per phase, its
share of the samples and the CPU it took per point in nanoseconds (all threads), by category
(LAZ decoding, MOSPT placement, acquisition order, sorts, zstd, page planes, copies, allocator,
kernel, other), and its top symbols. Phases are placed back from the last sample by the
durations the summary gives (the process ends right after the summary), so a few samples at a
boundary may land in the neighbouring phase.
"""
import collections, json, os, re, subprocess, sys, tempfile

HZ = 999


# What a sample's symbol does, the first rule that matches (kernel samples by their object).
CATEGORIES = [
    (r"laz::", "LAZ decode"),
    (r"ZSTD|HUF_|HIST_|FSE_", "zstd"),
    (r"mospt", "MOSPT places"),
    (r"order::", "acquisition order"),
    (r"sort", "sorts"),
    (r"page::", "page planes"),
    (r"memmove|memcpy|memset", "copies"),
    (r"malloc|free|realloc|_int_|calloc", "allocator"),
]


def category(sym, dso):
    if "kernel" in dso:
        return "kernel"
    return next((name for pattern, name in CATEGORIES if re.search(pattern, sym)), "other")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    exe, scan, extra = sys.argv[1], sys.argv[2], sys.argv[3:]
    with tempfile.TemporaryDirectory(dir=".") as tmp:
        data, out = os.path.join(tmp, "perf.data"), os.path.join(tmp, "out.myr")
        run = subprocess.run(
            ["perf", "record", "-F", str(HZ), "-o", data, "--", exe, "convert", scan,
             "-o", out, "--json", *extra],
            capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit(f"perf record failed: {run.stderr.strip()}")
        summary = json.loads(run.stdout)
        script = subprocess.run(["perf", "script", "-i", data, "-F", "time,ip,sym,dso"],
                                capture_output=True, text=True, errors="replace").stdout
    samples = []
    for line in script.splitlines():
        m = re.match(r"\s*([\d.]+):\s+[0-9a-f]+\s+(.*?)\s+\((.*)\)\s*$", line)
        if m:
            samples.append((float(m.group(1)), re.sub(r"\+0x[0-9a-f]+$", "", m.group(2)),
                            m.group(3)))
    if not samples:
        sys.exit("no samples")
    phases = [(p["phase"], p["seconds"]) for p in summary["phases"]]
    start = samples[-1][0] - sum(s for _, s in phases)
    bounds, t = [], start
    for name, s in phases:
        bounds.append((name, t, t + s))
        t += s
    per = collections.defaultdict(collections.Counter)
    syms = collections.defaultdict(collections.Counter)
    for t, sym, dso in samples:
        phase = "start" if t < start else next(
            (n for n, a, b in bounds if a <= t <= b), bounds[-1][0])
        per[phase][category(sym, dso)] += 1
        syms[phase][sym[:80]] += 1
    points = summary["points"]
    ns = lambda n: n / HZ / points * 1e9
    print(f"{os.path.basename(scan)}: {points} points, {summary['seconds']:.2f} s, "
          f"{len(samples)} samples at {HZ} Hz, {ns(len(samples)):.0f} ns of CPU a point")
    for phase in ["start"] + [n for n, _ in phases]:
        c = per.get(phase)
        if not c:
            continue
        total = sum(c.values())
        print(f"  {phase}: {100 * total / len(samples):.1f} % of samples, {ns(total):.0f} ns/pt: "
              + ", ".join(f"{k} {ns(v):.0f}" for k, v in c.most_common()))
        print("    top: " + "; ".join(f"{s} {100 * v / total:.0f} %"
                                      for s, v in syms[phase].most_common(5)))


if __name__ == "__main__":
    main()
