"""Small helpers shared by the validation scripts: the PLY view-stream reader, view metadata,
poses and a shell runner. numpy only (Debian's /usr/bin/python3)."""
import argparse
import datetime
import json
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
             "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
             "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
             "float64": "f8"}


def read_stream(path):
    """Documents of a binary little-endian PLY stream: [(comments, vertex record array)]."""
    data = open(path, "rb").read()
    pos, docs = 0, []
    while pos < len(data):
        end = data.index(b"end_header\n", pos) + len(b"end_header\n")
        header = data[pos:end].decode("ascii", "replace").splitlines()
        comments, fields, count, element, faces = [], [], 0, None, 0
        for line in header:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "comment":
                comments.append(line[len("comment "):])
            elif parts[0] == "element":
                element = parts[1]
                if element == "vertex":
                    count = int(parts[2])
                elif element == "face":
                    faces = int(parts[2])
            elif parts[0] == "property" and element == "vertex":
                fields.append((parts[-1], "<" + PLY_TYPES[parts[1]]))
            elif parts[0] == "format" and parts[1] != "binary_little_endian":
                sys.exit(f"{path}: only binary_little_endian streams are supported")
        if faces:
            sys.exit(f"{path}: meshes are not supported here")
        dtype = np.dtype(fields)
        verts = np.frombuffer(data, dtype=dtype, count=count, offset=end)
        pos = end + count * dtype.itemsize
        docs.append((comments, verts))
    return docs


def meta(comments, key):
    """Value of `comment rgbd:<key> ...`, or None."""
    for c in comments:
        m = re.match(r"rgbd:" + re.escape(key) + r"\s+(.*)$", c)
        if m:
            return m.group(1).strip()
    return None


def pose_of(comments):
    """4x4 world_from_sensor of a document, or None."""
    v = meta(comments, "pose.world_from_sensor")
    if v is None:
        return None
    m = np.eye(4)
    m[:3, :] = np.array([float(x) for x in v.split()]).reshape(3, 4)
    return m


def xyz_of(doc):
    return np.stack([doc["x"], doc["y"], doc["z"]], 1).astype(np.float64)


def rgb_of(doc):
    if "red" not in doc.dtype.names:
        return None
    return np.stack([doc["red"], doc["green"], doc["blue"]], 1).astype(np.float64) / 255.0


def argument_parser(doc):
    """The measurement scripts' command line: `doc` (the script's docstring) as its help, --bin
    (the built tools) and --work (the scratch folder of work_folder())."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--bin", default="build/bin", help="folder of the built rgbd-* tools")
    ap.add_argument("--work", default=None, help="scratch folder (default: a new temporary one)")
    return ap


def work_folder(script, work=None, needs=None):
    """A script's scratch folder: `work` (made when missing) or a new temporary one named after
    the script. With `needs`, first exits naming that path when it is absent (test data that
    lives in ../shared/data beside the repository)."""
    if needs is not None and not os.path.exists(needs):
        sys.exit(f"{script}: {needs} not found (../shared/data beside the repository)")
    work = work or tempfile.mkdtemp(prefix=script + "_")
    os.makedirs(work, exist_ok=True)
    return work


def write_json_lines(path, rows):
    """One JSON object per line (the --out files of the measurement scripts); nothing when
    `path` is empty or None (no --out given)."""
    if not path:
        return
    with open(path, "w") as f:
        for r in rows:
            f.write(json.dumps(r) + "\n")


def run_stamp(folder):
    """(today's ISO date, the short commit of the checkout that holds `folder`, or "unknown"):
    what names a results file."""
    commit = subprocess.run(["git", "-C", folder, "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip() or "unknown"
    return datetime.date.today().isoformat(), commit


def publish(text, out_dir, name, date, commit):
    """Prints a results table and, with `out_dir`, writes it to out_dir/<date>-<name>-<commit>.md
    (validation/results/ keeps them)."""
    print(text)
    if out_dir:
        path = os.path.join(out_dir, f"{date}-{name}-{commit}.md")
        with open(path, "w") as f:
            f.write(text)
        print(f"written {path}", file=sys.stderr)


def run(cmd, **kw):
    r = subprocess.run(cmd, shell=True, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"failed: {cmd}\n{r.stderr}")
    return r.stdout


# ../shared/data beside the repository, and the busts of the validation scripts with the
# rgbd-synth arguments that size and orient them (mesh path relative to DATA).
DATA = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..",
                                     "..", "shared", "data", "meshes"))
BUSTS = {
    "max_planck": ("max_planck/max-planck.obj", ["--height-m", "0.6"]),
    "bust_man_wreath": ("danish_statues/BustManWreath_welded.ply",
                        ["--height-m", "0.605", "--up", "y"]),
}


def write_points(path, xyz, normals=None, rgb=None):
    """One world-frame point document (binary PLY view stream) with optional normals / colours."""
    n = len(xyz)
    fields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    header = ("ply\nformat binary_little_endian 1.0\ncomment rgbd:stream 1\n"
              "comment rgbd:kind points\ncomment rgbd:view.id 0\ncomment rgbd:view.frame world\n"
              f"element vertex {n}\nproperty double x\nproperty double y\nproperty double z\n")
    if normals is not None:
        fields += [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
        header += "property float nx\nproperty float ny\nproperty float nz\n"
    if rgb is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
        header += "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    rec = np.zeros(n, dtype=fields)
    rec["x"], rec["y"], rec["z"] = np.asarray(xyz).T
    if normals is not None:
        rec["nx"], rec["ny"], rec["nz"] = np.asarray(normals).T
    if rgb is not None:
        rec["red"], rec["green"], rec["blue"] = np.asarray(rgb).T
    with open(path, "wb") as f:
        f.write((header + "end_header\n").encode("ascii"))
        f.write(rec.tobytes())

