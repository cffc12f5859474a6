#!/usr/bin/python3
"""One capture of the collection workflow (workflows/Snakefile): runs
    rgbd-reconstruct CAPTURE -o OUTDIR/mesh.ply --report OUTDIR/report --threads T -q ARGS
and writes OUTDIR/status.json (atomically, last): status ok or failed, the error in one line
(the tool's last stderr line, or why it could not start), exit code, wall time and the command.
The tool's stderr goes to OUTDIR/reconstruct.log. A failure leaves no mesh or report of an
earlier run behind and still exits 0, so that Snakemake goes on with the other captures and
the index lists the failure; this script exits 1 only when it cannot write status.json.
"""
import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
import time


def one_line(text):
    """The last non-empty line of a tool's stderr, or a fallback."""
    lines = [ln.strip() for ln in (text or "").splitlines() if ln.strip()]
    return lines[-1] if lines else ""


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reconstruct", required=True, help="path of rgbd-reconstruct")
    ap.add_argument("--capture", required=True, help="capture folder")
    ap.add_argument("--outdir", required=True, help="result folder of this capture")
    ap.add_argument("--threads", type=int, default=1, help="worker threads of the tool")
    ap.add_argument("--args", default="", help="more rgbd-reconstruct options (one string)")
    a = ap.parse_args()

    os.makedirs(a.outdir, exist_ok=True)
    mesh = os.path.join(a.outdir, "mesh.ply")
    report = os.path.join(a.outdir, "report")
    for stale in (mesh, ):
        if os.path.exists(stale):
            os.remove(stale)
    shutil.rmtree(report, ignore_errors=True)
    cmd = [a.reconstruct, a.capture, "-o", mesh, "--report", report,
           "--threads", str(a.threads), "-q"] + shlex.split(a.args)
    t0 = time.time()
    try:
        r = subprocess.run(cmd, capture_output=True, text=True)
        code, err = r.returncode, r.stderr
        error = one_line(err) if code != 0 else ""
        if code != 0 and not error:
            error = f"rgbd-reconstruct exited with {code} and no message"
        if code < 0:
            error = f"rgbd-reconstruct killed by signal {-code}" + (f": {error}" if error else "")
    except OSError as e:
        code, err, error = 127, str(e), f"cannot run {a.reconstruct}: {e.strerror}"
    wall = time.time() - t0
    with open(os.path.join(a.outdir, "reconstruct.log"), "w") as f:
        f.write("$ " + " ".join(shlex.quote(c) for c in cmd) + "\n" + (err or ""))
    ok = code == 0 and os.path.exists(mesh)
    if code == 0 and not ok:
        error = "rgbd-reconstruct exited 0 but wrote no mesh"
    if not ok:
        if os.path.exists(mesh):
            os.remove(mesh)
    status = {
        "name": os.path.basename(os.path.normpath(a.capture)),
        "capture": os.path.abspath(a.capture),
        "status": "ok" if ok else "failed",
        "error": error.replace("\n", " ")[:500],
        "exit_code": code,
        "wall_s": round(wall, 3),
        "mesh": "mesh.ply" if ok else None,
        "report": "report/index.html" if ok and os.path.exists(
            os.path.join(report, "index.html")) else None,
        "metrics": "report/metrics.json" if ok and os.path.exists(
            os.path.join(report, "metrics.json")) else None,
        "host": os.uname().nodename,
        "command": cmd,
    }
    path = os.path.join(a.outdir, "status.json")
    tmp = path + f".tmp-{os.getpid()}"
    try:
        with open(tmp, "w") as f:
            json.dump(status, f, indent=2)
            f.write("\n")
        os.replace(tmp, path)
    except OSError as e:
        sys.exit(f"reconstruct_one: cannot write {path}: {e.strerror}")


if __name__ == "__main__":
    main()
