#!/usr/bin/python3
"""ctest workflows/collection: runs workflows/Snakefile on three tiny synthetic turntable
captures (rgbd-synth --rig turntable --stops 8 --resolution-scale 0.4 of an ellipsoid written
here, 16 cm tall), one of them deliberately broken (truncated rig.json), and checks:
- the two good captures give results/<name>/mesh.ply, closed, within 2 mm of the true surface
  on 90% of it (F@2mm of the report's evaluation against gt/mesh.ply), and a report;
- results/index.html has one row per capture: two "ok" rows with their picture and figures, one
  "failed" row that names rig.json (the error in one line), and the failure stopped nobody;
- a second run does nothing (Snakemake says so and no result file changes);
- changing one capture's file re-runs that capture only.
Usage: collection_test.py SOURCE_DIR BIN_DIR. Exit 0 pass, 1 fail, 77 skip (no snakemake).
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

SKIP = 77


def fail(msg):
    print(f"FAIL: {msg}")
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)
    print(f"ok: {msg}")


def write_ellipsoid(path, a=0.05, b=0.035, c=0.08, n_lat=40, n_lon=64):
    """A closed triangulated ellipsoid (OFF, metres, z up): the known shape."""
    verts = [(0.0, 0.0, c)]
    for i in range(1, n_lat):
        th = math.pi * i / n_lat
        for j in range(n_lon):
            ph = 2 * math.pi * j / n_lon
            verts.append((a * math.sin(th) * math.cos(ph), b * math.sin(th) * math.sin(ph),
                          c * math.cos(th)))
    verts.append((0.0, 0.0, -c))
    idx = lambda i, j: 1 + (i - 1) * n_lon + (j % n_lon)  # noqa: E731
    faces = [(0, idx(1, j), idx(1, j + 1)) for j in range(n_lon)]
    for i in range(1, n_lat - 1):
        for j in range(n_lon):
            faces += [(idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)),
                      (idx(i, j), idx(i + 1, j + 1), idx(i, j + 1))]
    last = len(verts) - 1
    faces += [(last, idx(n_lat - 1, j + 1), idx(n_lat - 1, j)) for j in range(n_lon)]
    with open(path, "w") as f:
        f.write(f"OFF\n{len(verts)} {len(faces)} 0\n")
        f.writelines(f"{x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in verts)
        f.writelines(f"3 {p} {q} {r}\n" for p, q, r in faces)


def run(cmd, cwd, env=None):
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env)
    return r.returncode, r.stdout + r.stderr


def snapshot(results):
    """mtime of every result file (not Snakemake's own records)."""
    out = {}
    for d, subdirs, names in os.walk(results):
        subdirs[:] = [s for s in subdirs if s != ".snakemake"]
        for n in names:
            p = os.path.join(d, n)
            out[p] = os.stat(p).st_mtime_ns
    return out


def main():
    src, bindir = sys.argv[1], sys.argv[2]
    if shutil.which("snakemake") is None:
        print("SKIP: snakemake is not installed (Debian package snakemake; scripts/setup.sh)")
        return SKIP
    tmp = tempfile.mkdtemp(prefix="rgbd-collection-")
    try:
        caps, results = os.path.join(tmp, "captures"), os.path.join(tmp, "results")
        os.makedirs(caps)
        mesh = os.path.join(tmp, "ellipsoid.off")
        write_ellipsoid(mesh)
        for name, seed in (("egg_a", 1), ("egg_b", 2), ("egg_broken", 3)):
            code, out = run([os.path.join(bindir, "rgbd-synth"), mesh, "-o",
                             os.path.join(caps, name), "--rig", "turntable", "--stops", "8",
                             "--resolution-scale", "0.4", "--height-m", "0.16", "--up", "z",
                             "--seed", str(seed), "-q"], tmp)
            check(code == 0, f"rgbd-synth {name}" + ("" if code == 0 else f": {out}"))
        rig = os.path.join(caps, "egg_broken", "rig.json")
        text = open(rig).read()
        with open(rig, "w") as f:
            f.write(text[: len(text) // 2])  # truncated: not valid JSON

        snake = ["snakemake", "-s", os.path.join(src, "workflows", "Snakefile"), "--cores", "2",
                 "--config", f"captures={caps}", f"results={results}", f"bin={bindir}"]
        t0 = time.time()
        code, out = run(snake, tmp)
        check(code == 0, f"first run exits 0 ({time.time() - t0:.0f} s)" +
              ("" if code == 0 else f"\n{out[-3000:]}"))

        for name in ("egg_a", "egg_b"):
            d = os.path.join(results, name)
            check(os.path.getsize(os.path.join(d, "mesh.ply")) > 1000, f"{name}: mesh.ply")
            st = json.load(open(os.path.join(d, "status.json")))
            check(st["status"] == "ok" and st["error"] == "", f"{name}: status ok")
            m = json.load(open(os.path.join(d, "report", "metrics.json")))
            check(m["mesh"]["reconstruction"]["closed"] is True, f"{name}: mesh closed")
            f2 = m["evaluation"]["surface"]["fscore_2mm"]
            check(f2 >= 0.90, f"{name}: F@2mm {f2:.3f} >= 0.90 against the true ellipsoid")
            check(os.path.exists(os.path.join(d, "report", "result.png")), f"{name}: picture")
        d = os.path.join(results, "egg_broken")
        st = json.load(open(os.path.join(d, "status.json")))
        check(st["status"] == "failed" and st["exit_code"] != 0, "egg_broken: status failed")
        check("rig.json" in st["error"] and "\n" not in st["error"],
              f"egg_broken: one-line error naming rig.json ({st['error'][:80]}...)")
        check(not os.path.exists(os.path.join(d, "mesh.ply")), "egg_broken: no mesh")

        page = open(os.path.join(results, "index.html")).read()
        rows = re.findall(r'<tr class="(ok|failed)">(.*?)</tr>', page, re.S)
        check(len(rows) == 3, f"index: 3 rows ({len(rows)})")
        by_name = {re.search(r"<td>([^<]*)</td>", r).group(1): (c, r) for c, r in rows}
        check(sorted(by_name) == ["egg_a", "egg_b", "egg_broken"], "index: one row per capture")
        for name in ("egg_a", "egg_b"):
            c, r = by_name[name]
            check(c == "ok" and f'src="{name}/report/result.png"' in r and
                  f'href="{name}/mesh.ply"' in r and "yes" in r, f"index: {name} row ok")
            f1 = json.load(open(os.path.join(results, name, "report", "metrics.json")))[
                "evaluation"]["surface"]["fscore_1mm"]
            check(f"{f1:.3f}" in r, f"index: {name} shows F@1mm {f1:.3f}")
        c, r = by_name["egg_broken"]
        check(c == "failed" and "rig.json" in r, "index: egg_broken row failed with its error")

        before = snapshot(results)
        code, out = run(snake, tmp)
        check(code == 0 and "Nothing to be done" in out, "second run: nothing to be done")
        check(snapshot(results) == before, "second run: no result file changed")

        # Snakemake 7 re-runs on a newer input only when its content changed (checksums).
        with open(os.path.join(caps, "egg_b", "rig.json"), "a") as f:
            f.write("\n")
        code, out = run(snake, tmp)
        after = snapshot(results)
        changed = sorted({os.path.relpath(p, results).split(os.sep)[0]
                          for p in after if after[p] != before.get(p)})
        good = code == 0 and changed == ["egg_b", "index.html"]
        check(good, f"changing egg_b re-runs egg_b and the index only ({changed})" +
              ("" if good else "\n" + out[-2000:]))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
