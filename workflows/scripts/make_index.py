#!/usr/bin/python3
"""The collection's page (workflows/Snakefile): results/index.html with one row per capture,
from each results/<name>/status.json and, for the ones that succeeded, report/metrics.json of
rgbd-reconstruct: the report's picture of the result (report/result.png) linking to the report,
views used, faces, closed or not, and with ground truth F@1mm, F@2mm, completeness and accuracy
means and invented surface; links to the mesh, the report and the log. A failed capture's row
carries its error in one line. Written atomically (temp file, rename).
"""
import argparse
import html
import json
import os
import sys
import time


def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        return {"status": "failed", "error": f"{path}: unreadable status ({e})"}


def fmt(v, scale=1.0, digits=3, suffix=""):
    if v is None:
        return "&ndash;"
    return f"{v * scale:.{digits}f}{suffix}"


def row(status_path, out_dir):
    d = os.path.dirname(status_path)
    rel = os.path.relpath(d, out_dir)
    s = load(status_path)
    name = s.get("name") or os.path.basename(d)
    link = lambda f, text: f'<a href="{html.escape(rel + "/" + f)}">{text}</a>'  # noqa: E731
    if s.get("status") != "ok":
        log = link("reconstruct.log", "log") if os.path.exists(
            os.path.join(d, "reconstruct.log")) else ""
        return (f'<tr class="failed"><td>{html.escape(name)}</td><td>failed</td>'
                f'<td colspan="9" class="error">{html.escape(s.get("error") or "unknown error")}'
                f'</td><td>{log}</td></tr>'), s
    m = {}
    if s.get("metrics"):
        m = load(os.path.join(d, s["metrics"]))
    counts = m.get("counts", {})
    rec = m.get("mesh", {}).get("reconstruction", {})
    surf = m.get("evaluation", {}).get("surface", {})
    total = m.get("timings_s", {}).get("total", s.get("wall_s"))
    pic = ""
    if os.path.exists(os.path.join(d, "report", "result.png")):
        pic = link("report/index.html",
                   f'<img src="{html.escape(rel)}/report/result.png" alt="{html.escape(name)}">')
    links = " ".join(x for x in [
        link("mesh.ply", "mesh"),
        link("report/index.html", "report") if s.get("report") else "",
        link("reconstruct.log", "log")] if x)
    closed = rec.get("closed")
    cells = [
        html.escape(name), pic,
        str(counts.get("views", "&ndash;")),
        str(counts.get("mesh_faces", "&ndash;")),
        "yes" if closed else ("no" if closed is False else "&ndash;"),
        fmt(surf.get("fscore_1mm")), fmt(surf.get("fscore_2mm")),
        fmt(surf.get("completeness_mean_m"), 1e3, 2),
        fmt(surf.get("accuracy_mean_m"), 1e3, 2),
        fmt(surf.get("invented_surface_fraction"), 100, 2, " %"),
        fmt(total, 1, 1), links]
    return '<tr class="ok">' + "".join(f"<td>{c}</td>" for c in cells) + "</tr>", s


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("status", nargs="*", help="results/<name>/status.json files")
    ap.add_argument("-o", "--output", required=True, help="index.html to write")
    ap.add_argument("--captures", default="", help="captures folder (shown in the header)")
    a = ap.parse_args()
    out_dir = os.path.dirname(os.path.abspath(a.output))
    rows, failed = [], 0
    for p in sorted(a.status, key=lambda p: os.path.basename(os.path.dirname(p))):
        r, s = row(os.path.abspath(p), out_dir)
        rows.append(r)
        failed += s.get("status") != "ok"
    head = ("<tr><th>object</th><th>result</th><th>views</th><th>faces</th><th>closed</th>"
            "<th>F@1mm</th><th>F@2mm</th><th>completeness mean (mm)</th>"
            "<th>accuracy mean (mm)</th><th>invented</th><th>time (s)</th><th>files</th></tr>")
    page = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>rgbd-toolkit collection</title>
<style>
body {{ font-family: sans-serif; margin: 1em; }}
table {{ border-collapse: collapse; }}
td, th {{ border: 1px solid #ccc; padding: 4px 8px; text-align: right; }}
td:first-child, th:first-child {{ text-align: left; }}
td img {{ height: 120px; }}
tr.failed td {{ background: #fdd; }}
td.error {{ text-align: left; font-family: monospace; }}
</style></head><body>
<h1>Collection: {len(rows)} captures, {len(rows) - failed} reconstructed, {failed} failed</h1>
<p>Captures: {html.escape(a.captures)}. Written {time.strftime("%Y-%m-%d %H:%M:%S %Z")} by
workflows/Snakefile (rgbd-reconstruct per capture). Metrics against the ground truth only
where the capture has one (gt/ of rgbd-synth); invented surface: share of the mesh's area
farther than 5 mm from the truth.</p>
<table>
{head}
{chr(10).join(rows)}
</table></body></html>
"""
    tmp = a.output + f".tmp-{os.getpid()}"
    try:
        with open(tmp, "w") as f:
            f.write(page)
        os.replace(tmp, a.output)
    except OSError as e:
        sys.exit(f"make_index: cannot write {a.output}: {e.strerror}")


if __name__ == "__main__":
    main()
