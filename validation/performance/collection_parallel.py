#!/usr/bin/python3
"""Collection workflow throughput (issue 23): N small synthetic turntable captures reconstructed
(a) one after another by a shell-style loop of `rgbd-reconstruct CAP -o mesh.ply --report DIR`
    (each run with all cores, --threads 0: what a user's own loop does), and
(b) by the workflow, `snakemake -s workflows/Snakefile --cores 2 --config captures=...
    results=... bin=...` (two captures at a time, one thread each),
on the same captures in the same run; prints a markdown table with both wall times and the
ratio workflow / loop (target: <= 1). Captures: the ellipsoid of
tests/workflows/collection_test.py (10 x 7 x 16 cm), --rig turntable --stops 12
--resolution-scale 0.4, seeds 1..N.

    /usr/bin/python3 validation/performance/collection_parallel.py --bin build/bin [-n 10]
        [--cores 2] [--out validation/results/]
With --out, the table also goes to OUT/<date>-collection-parallel-<commit>.md.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(SRC, "tests", "workflows"))
sys.path.insert(0, os.path.join(SRC, "validation", "quality", "common"))
from collection_test import write_ellipsoid  # noqa: E402
from rgbd_stream import publish, run_stamp  # noqa: E402


def sh(cmd, cwd=None):
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"collection_parallel: failed ({r.returncode}): {' '.join(cmd)}\n"
                 f"{r.stderr[-3000:]}")
    return r.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True, help="folder with rgbd-synth and rgbd-reconstruct")
    ap.add_argument("-n", type=int, default=10, help="number of captures (10)")
    ap.add_argument("--cores", type=int, default=2, help="snakemake --cores (2)")
    ap.add_argument("--stops", type=int, default=12, help="turntable stops per capture (12)")
    ap.add_argument("--out", help="folder for the dated markdown copy of the table")
    a = ap.parse_args()
    b = os.path.abspath(a.bin)
    if shutil.which("snakemake") is None:
        sys.exit("collection_parallel: snakemake is not installed (apt-get install snakemake)")
    tmp = tempfile.mkdtemp(prefix="rgbd-collection-bench-")
    try:
        caps = os.path.join(tmp, "captures")
        os.makedirs(caps)
        mesh = os.path.join(tmp, "ellipsoid.off")
        write_ellipsoid(mesh)
        for i in range(a.n):
            sh([f"{b}/rgbd-synth", mesh, "-o", os.path.join(caps, f"egg{i:02d}"), "--rig",
                "turntable", "--stops", str(a.stops), "--resolution-scale", "0.4",
                "--height-m", "0.16", "--up", "z", "--seed", str(i + 1), "-q"])
        names = sorted(os.listdir(caps))

        loop_dir = os.path.join(tmp, "loop")
        t0 = time.perf_counter()
        for n in names:
            d = os.path.join(loop_dir, n)
            os.makedirs(d)
            sh([f"{b}/rgbd-reconstruct", os.path.join(caps, n), "-o", f"{d}/mesh.ply",
                "--report", f"{d}/report", "-q"])
        t_loop = time.perf_counter() - t0

        res = os.path.join(tmp, "results")
        t0 = time.perf_counter()
        sh(["snakemake", "-s", os.path.join(SRC, "workflows", "Snakefile"), "--cores",
            str(a.cores), "--config", f"captures={caps}", f"results={res}", f"bin={b}"],
           cwd=tmp)
        t_wf = time.perf_counter() - t0
        ok = sum(os.path.exists(os.path.join(res, n, "mesh.ply")) for n in names)
        t0 = time.perf_counter()
        sh(["snakemake", "-s", os.path.join(SRC, "workflows", "Snakefile"), "--cores",
            str(a.cores), "--config", f"captures={caps}", f"results={res}", f"bin={b}"],
           cwd=tmp)
        t_again = time.perf_counter() - t0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    date, commit = run_stamp(SRC)
    ratio = t_wf / t_loop
    lines = [
        f"# Collection workflow vs a loop ({date}, commit {commit})",
        "",
        f"Command: `/usr/bin/python3 validation/performance/collection_parallel.py --bin "
        f"{a.bin} -n {a.n} --cores {a.cores} --stops {a.stops}`",
        f"Machine: {os.cpu_count()} cores (shared with other work; wall times).",
        f"Captures: {a.n} synthetic SR300 turntable captures of a 16 cm ellipsoid, {a.stops} "
        "stops, --resolution-scale 0.4 (256x192 depth).",
        "",
        "| run | wall (s) | per capture (s) | meshes |",
        "| --- | ---: | ---: | ---: |",
        f"| loop: rgbd-reconstruct one after another (--threads 0) | {t_loop:.1f} | "
        f"{t_loop / a.n:.1f} | {a.n} |",
        f"| snakemake --cores {a.cores} (threads 1 per job) | {t_wf:.1f} | {t_wf / a.n:.1f} | "
        f"{ok} |",
        f"| snakemake again (all up to date) | {t_again:.1f} | | |",
        "",
        f"Ratio workflow / loop: **{ratio:.2f}** (target <= 1: "
        f"{'met' if ratio <= 1.0 else 'NOT met'}).",
    ]
    publish("\n".join(lines) + "\n", a.out, "collection-parallel", date, commit)
    return 0 if ok == a.n else 1


if __name__ == "__main__":
    sys.exit(main())
