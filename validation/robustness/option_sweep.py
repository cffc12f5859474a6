#!/usr/bin/python3
"""Bad option values over every tool (issue 21 item 4).

For every tool of BIN_DIR and every option its --help lists with a value, runs the tool on a
small valid input with that option set to each of a few bad values (-1, nan, 1e300, a
word) and checks the failure contract: a run that fails exits 1 (runtime) or 2 (usage),
never by a signal, its first stderr line is "<tool>: error: ..." naming the option or the
file, the only other stderr line is the usage hint, and it leaves no output file. A run that
succeeds is a breach too (issue 39: a tool must not accept an absurd value, nor ignore an
option of a mode not chosen), except the few in MEANINGFUL, where the value has a use (a
signed angle of -1 degrees). Prints one line per finding and a table; exits 1 on a breach.

Usage: option_sweep.py BIN_DIR [--tools rgbd-clean,rgbd-mesh] [--timeout 60] [--out FILE.md]
The inputs (a 2-sensor rgbd-synth capture of an ellipsoid, its views, a mesh) are made in a
temporary folder with the tools themselves.
"""
import argparse
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

BAD_VALUES = ["-1", "nan", "1e300", "bogus"]

# (tool, option, value) runs whose exit 0 is right: the value is a valid setting.
MEANINGFUL = {
    ("rgbd-render", "azimuth", "-1"): "a signed angle around up",
    ("rgbd-render", "elevation", "-1"): "a signed angle (-90..90, below the horizon)",
    ("rgbd-fill", "min-rim-radial", "-1"): "a cosine in [-1, 1]: -1 fills every rim",
    ("rgbd-fill", "top-min-up", "-1"): "a cosine in [-1, 1]: -1 takes any top",
}

# Options not swept: they name files or endpoints (their own contract cases live in
# tests/cli/failure_contract_test.cpp), or only change where output goes.
SKIP = {"help", "version", "output", "metrics", "input", "debug", "report", "listen", "hub",
        "control", "key", "server-key", "truth", "live", "rig", "reference", "points",
        "board", "mask", "baseline-points", "save-stages", "sensor", "o", "stages-dir",
        "make-key", "gt-poses", "capture", "video"}


def ellipsoid_off(path, nu=32, nv=16, rx=0.3, ry=0.5, rz=0.25):
    with open(path, "w") as f:
        f.write("OFF\n%d %d 0\n" % (nu * (nv - 1) + 2, 2 * nu * (nv - 1)))
        f.write("0 %g 0\n" % ry)
        for j in range(1, nv):
            for i in range(nu):
                th, ph = math.pi * j / nv, 2 * math.pi * i / nu
                f.write("%g %g %g\n" % (rx * math.sin(th) * math.cos(ph), ry * math.cos(th),
                                        rz * math.sin(th) * math.sin(ph)))
        f.write("0 %g 0\n" % -ry)
        south = nu * (nv - 1) + 1

        def vid(j, i):
            return 1 + (j - 1) * nu + (i % nu)
        for i in range(nu):
            f.write("3 0 %d %d\n" % (vid(1, i + 1), vid(1, i)))
        for j in range(1, nv - 1):
            for i in range(nu):
                f.write("3 %d %d %d\n" % (vid(j, i), vid(j, i + 1), vid(j + 1, i + 1)))
                f.write("3 %d %d %d\n" % (vid(j, i), vid(j + 1, i + 1), vid(j + 1, i)))
        for i in range(nu):
            f.write("3 %d %d %d\n" % (south, vid(nv - 1, i), vid(nv - 1, i + 1)))


def sh(cmd, cwd, timeout):
    """Runs `cmd`; on timeout ends its whole process group (the tool, not only the shell: a
    tool left running would write its output during the next run)."""
    t = time.time()
    p = subprocess.Popen(cmd, shell=True, cwd=cwd, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, errors="replace",
                         start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
        return p.returncode, out, err, time.time() - t
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        return None, "", "", time.time() - t


def options_of(bin_dir, tool):
    """(name, takes_value) of every long option in the tool's --help."""
    rc, out, _, _ = sh(os.path.join(bin_dir, tool) + " --help", None, 30)
    opts = []
    for line in out.splitlines():
        m = re.match(r"  (?:-\w \[ )?--([\w-]+)(?: \])?( [A-Za-z0-9_,.:#|\[\]]+)?", line)
        if m and m.group(1) not in [o for o, _ in opts]:
            opts.append((m.group(1), m.group(2) is not None and not m.group(2).startswith(" [")))
    return opts


# A command per tool that succeeds on the inputs made by make_inputs; OUT is the output name.
BASE = {
    "rgbd-cloud": "$BIN/rgbd-cloud cap -o OUT.ply -q",
    "rgbd-clean": "$BIN/rgbd-clean views.ply -o OUT.ply -q",
    "rgbd-align": "$BIN/rgbd-align views.ply -o OUT.ply -q",
    "rgbd-mesh": "$BIN/rgbd-mesh views.ply -o OUT.ply -q",
    "rgbd-fill": "$BIN/rgbd-fill views.ply -o OUT.ply -q",
    "rgbd-upsample": "$BIN/rgbd-upsample views.ply -o OUT.ply -q",
    "rgbd-eval": "$BIN/rgbd-eval mesh.ply --reference blob.off -o OUT.json -q",
    "rgbd-reconstruct": "$BIN/rgbd-reconstruct cap -o OUT.ply -q",
    "rgbd-info": "$BIN/rgbd-info views.ply",
    "rgbd-render": "$BIN/rgbd-render mesh.ply -o OUT.png -q",
    "rgbd-synth": "$BIN/rgbd-synth blob.off -o OUT --sensors 2 --frames 1 -q",
    "rgbd-calibrate": "$BIN/rgbd-calibrate cap -o OUT.json -q",
    "rgbd-capture": "$BIN/rgbd-capture --rig cap/rig.json -o OUT --duration-s 0.5 "
                    "--listen tcp://127.0.0.1:PORT -q",
    "rgbd-node": "$BIN/rgbd-node --sensor playback:cap#SENSOR --hub tcp://127.0.0.1:9 "
                 "--start-timeout-s 0.3 -q",
}


def make_inputs(bin_dir, work):
    ellipsoid_off(os.path.join(work, "blob.off"))
    steps = ["$BIN/rgbd-synth blob.off -o cap --sensors 2 --frames 1 --seed 3 -q",
             "$BIN/rgbd-cloud cap -o views.ply -q",
             "$BIN/rgbd-mesh views.ply -o mesh.ply -q"]
    for s in steps:
        rc, _, err, _ = sh(s.replace("$BIN", bin_dir), work, 600)
        if rc != 0:
            sys.exit("option_sweep: cannot make the inputs: %s: %s" % (s, err.strip()))
    sensor = sorted(d for d in os.listdir(os.path.join(work, "cap"))
                    if os.path.isdir(os.path.join(work, "cap", d)))[0]
    return sensor


def leftovers(work, before):
    return sorted(set(os.listdir(work)) - before)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bin_dir")
    ap.add_argument("--tools", default=",".join(BASE))
    ap.add_argument("--timeout", type=float, default=60)
    ap.add_argument("--out")
    a = ap.parse_args()
    bin_dir = os.path.abspath(a.bin_dir)
    work = tempfile.mkdtemp(prefix="rgbd_option_sweep_")
    try:
        sensor = make_inputs(bin_dir, work)
        before = set(os.listdir(work))
        breaches, accepted, rows = [], [], []
        port = 23000 + os.getpid() % 1000 * 2
        for tool in a.tools.split(","):
            base = BASE[tool].replace("$BIN", bin_dir).replace("SENSOR", sensor)
            for opt, takes_value in options_of(bin_dir, tool):
                if not takes_value or opt in SKIP:
                    continue
                for value in BAD_VALUES:
                    port += 2
                    cmd = base.replace("PORT", str(port)) + " --%s %s" % (opt, value)
                    rc, out, err, secs = sh(cmd, work, a.timeout)
                    lines = err.splitlines()
                    what = "%s --%s %s" % (tool, opt, value)
                    problem = None
                    if rc is None:
                        problem = "no answer after %.0f s" % secs
                    elif rc < 0 or rc >= 128:
                        problem = "killed by signal %d" % (-rc if rc < 0 else rc - 128)
                    elif rc == 0:
                        accepted.append((what, secs))
                        if (tool, opt, value) not in MEANINGFUL:
                            problem = "exit 0: the value was accepted (or the option ignored)"
                    elif rc not in (1, 2):
                        problem = "exit %d" % rc
                    elif not lines or not lines[0].startswith(tool + ": error: "):
                        problem = "first stderr line is not '%s: error: ...': %r" % (
                            tool, lines[:2])
                    elif len(lines) > 1 and not (len(lines) == 2 and lines[1].startswith("Try '")):
                        problem = "%d stderr lines: %r" % (len(lines), lines[:4])
                    elif opt not in lines[0] and rc == 2:
                        problem = "usage error does not name --%s: %s" % (opt, lines[0])
                    left = leftovers(work, before)
                    if rc not in (0, None) and left:
                        problem = (problem + "; " if problem else "") + "left " + ", ".join(left)
                    for name in left:
                        p = os.path.join(work, name)
                        shutil.rmtree(p) if os.path.isdir(p) else os.remove(p)
                    rows.append((what, rc, secs, lines[0] if lines else ""))
                    if problem:
                        breaches.append((what, problem))
                        print("BREACH %s: %s" % (what, problem), flush=True)
        report = ["| run | exit | s | first stderr line |", "|---|---|---|---|"]
        for what, rc, secs, line in rows:
            report.append("| `%s` | %s | %.1f | %s |" % (what, rc, secs,
                                                         line.replace("|", "\\|")[:150]))
        text = "\n".join(report) + "\n\nAccepted: " + (
            ", ".join("`%s`" % w for w, _ in accepted) or "none") + "\n\nBreaches: %d\n" % len(
            breaches) + "".join("- `%s`: %s\n" % b for b in breaches)
        if a.out:
            with open(a.out, "w") as f:
                f.write(text)
        print("option_sweep: %d runs, %d accepted, %d breaches" % (len(rows), len(accepted),
                                                                  len(breaches)))
        return 1 if breaches else 0
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
