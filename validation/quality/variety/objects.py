#!/usr/bin/python3
"""The variety object set of the ablation benchmark: meshes of different shapes with the
rgbd-synth arguments that render each one (validation/quality/ablation/ablation.py
--objects-dir DIR or --variety).

    /usr/bin/python3 validation/quality/variety/objects.py --out DIR [--objects A,B] [--shared DIR]

writes DIR/<name>.off|.ply (a copy of the source mesh, or a procedural mesh) and
DIR/objects.json: {"objects": [{name, file, kind, synth, scene, provenance, ...}]} where
- kind: bust, figure, animal, seated, thin or turntable;
- synth: the rgbd-synth arguments (--up, --height-m, --rig, turntable options);
- scene: rgbd-synth scene options (--floor ...) that the runner passes only when the
  rgbd-synth in use lists them in its --help (older builds render the object alone).

Sources: Debian's libcgal-dev demo data (/usr/share/doc/libcgal-dev/data.tar.gz,
data/meshes/*.off), ../shared/data/meshes beside the checkout (the busts; left out when absent),
and procedural meshes made here with numpy: unions of closed parts (capsules, boxes,
ellipsoids, surfaces of revolution, a capped tube) of which only the outer surface is written
(each part's faces inside another part dropped: the truth must not hold hidden inner walls,
which would count as unseen surface; the seams where parts meet stay open):
- cellist: a seated figure (capsules, boxes, ellipsoids) on a chair whose four legs stand at the
  lowest point (the floor), with a cello between the knees (its end pin on the floor) and a
  bow 10 mm thick (5 mm radius) held across the strings: closure of a seated figure, thin parts;
- jug: a revolved jug with a 6 mm wall and a handle tube of 12 mm radius: a thin handle;
- puppet: a marionette-like figure (sphere head, hat cone, cloth cone body, thin capsule arms,
  hands, feet) on the SR300 turntable rig at 0.28 m.
Chosen CGAL meshes (inspected: vertex and face counts, boundary edges, up axis from
orthographic views): lion-head (bust, y up, neck cut: 36 boundary edges), mannequin-devil (a
horned head and neck, z up, 64 boundary edges at the neck), man (standing figure, z up,
closed), homer (y up, closed), armadillo (y up, closed), elephant, cow, bull, camel (y up),
bunny00 (animals, closed), bear (a teddy: ears, y up, closed). The two neck cuts are capped by
a fan (cap_holes) so that the truth is closed like the reconstruction. Left out: nefertiti (a
299-vertex face shell, open at the back), mpi (a 90-vertex blob), handle (a bar), hand (a fist).

Ring geometry (rgbd-synth's fixed defaults): 8 Kinect v2 sensors 1.5 m from the axis at 1.6 m
height, tilted 10 deg down, the object's bbox centre at 1.335 m; the sensors see from about
0.55 m to 2.1 m height near the object, so a standing figure of 1.4 m fits the views (the
reconstruction's 0.6 m crop sphere does not hold it: a finding, not a choice).
"""
import argparse
import json
import os
import shutil
import sys
import tarfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.normpath(os.path.join(HERE, "..", "..", "..", "..", "shared", "data", "meshes"))
CGAL_DATA = "/usr/share/doc/libcgal-dev/data.tar.gz"
CGAL = "Debian libcgal-dev demo data (" + CGAL_DATA + "): data/meshes/"
FLOOR = ["--floor"]  # the scene options of the seated figure and one standing figure

# name: (source, file, kind, up, height_m, extra rgbd-synth args, scene, note)
CATALOGUE = [
    ("max_planck", "shared", "max_planck/max-planck.obj", "bust", "y", 0.6, [], [],
     "bust of ../shared (as rgbd_stream.BUSTS)"),
    ("bust_man_wreath", "shared", "danish_statues/BustManWreath_welded.ply", "bust", "y", 0.605,
     [], [], "bust of ../shared (as rgbd_stream.BUSTS)"),
    ("lion_head", "cgal", "lion-head.off", "bust", "y", 0.5, [], [],
     "lion head cut at the neck (36 boundary edges)"),
    ("mannequin_devil", "cgal", "mannequin-devil.off", "bust", "z", 0.45, [], [],
     "horned head and neck, cut at the neck (64 boundary edges)"),
    ("man", "cgal", "man.off", "figure", "z", 1.4, [], FLOOR,
     "standing man, closed; 1.4 m: in the sensors' views"),
    ("homer", "cgal", "homer.off", "figure", "y", 1.0, [], [], "standing Homer, closed"),
    ("armadillo", "cgal", "armadillo.off", "figure", "y", 0.9, [], [],
     "standing armadillo, closed"),
    ("bunny", "cgal", "bunny00.off", "animal", "y", 0.45, [], [],
     "as ablation.py's bunny"),
    ("elephant", "cgal", "elephant.off", "animal", "y", 0.6, [], [], "closed; trunk raised"),
    ("cow", "cgal", "cow.off", "animal", "y", 0.5, [], [], "closed; thin legs, horns"),
    ("bull", "cgal", "bull.off", "animal", "y", 0.55, [], [], "closed; running, tail up"),
    ("camel", "cgal", "camel.off", "animal", "y", 0.9, [], [], "closed; long thin legs"),
    ("bear", "cgal", "bear.off", "animal", "y", 0.5, [], [], "teddy bear, closed; ears"),
    ("cellist", "procedural", None, "seated", "z", None, [], FLOOR,
     "seated figure on a chair on the floor, cello, bow 10 mm thick"),
    ("jug", "procedural", None, "thin", "z", None, [], [],
     "revolved jug, 6 mm wall, handle tube 24 mm thick"),
    ("puppet", "procedural", None, "turntable", "z", 0.28,
     ["--rig", "turntable", "--stops", "12", "--stand"], [],
     "marionette-like figure on the SR300 turntable rig"),
]


# --------------------------------------------------------------------------- closed parts


class Mesh:
    """Triangle soup of closed parts: vertices (n, 3) metres, faces (m, 3)."""

    def __init__(self):
        self.v, self.f = [], []
        self.n = 0

    def add(self, v, f):
        self.v.append(np.asarray(v, float))
        self.f.append(np.asarray(f, int) + self.n)
        self.n += len(v)
        return self

    def arrays(self):
        """The outer surface of the union: every part's faces whose centroid lies inside another
        part are dropped (the truth the scorer compares with must hold only what a sensor can
        see from outside; the seams where parts meet stay open), unused vertices removed."""
        v = np.concatenate(self.v)
        keep = []
        for i, f in enumerate(self.f):
            c = v[f].mean(1)
            inside = np.zeros(len(f), bool)
            for j in range(len(self.f)):
                if j != i:
                    inside |= self.inside(j, c)
            keep.append(f[~inside])
        f = np.concatenate(keep)
        used = np.unique(f)
        remap = np.full(len(v), -1)
        remap[used] = np.arange(len(used))
        return v[used], remap[f]

    def inside(self, j, points):
        """Which points lie inside closed part j: the side of the closest triangle's plane
        (Open3D closest-point queries; its ray casts return no hits on this machine's build)."""
        import open3d as o3d
        vj = self.v[j]
        fj = self.f[j] - sum(len(x) for x in self.v[:j])
        lo, hi = vj.min(0), vj.max(0)
        near = np.all((points >= lo) & (points <= hi), 1)
        out = np.zeros(len(points), bool)
        if not near.any():
            return out
        a, b, c = vj[fj[:, 0]], vj[fj[:, 1]], vj[fj[:, 2]]
        n = np.cross(b - a, c - a)
        if np.einsum("ij,ij->", a, n) < 0:  # six times the signed volume: inward faces
            n = -n
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(vj.astype(np.float32)),
                            o3d.core.Tensor(fj.astype(np.uint32)))
        q = points[near].astype(np.float32)
        r = scene.compute_closest_points(o3d.core.Tensor(q))
        cp, tri = r["points"].numpy(), r["primitive_ids"].numpy()
        out[np.flatnonzero(near)] = np.einsum("ij,ij->i", q - cp, n[tri]) < -1e-6
        return out


def revolve(profile, seg=48, step=0.01):
    """Closed surface of revolution about z of a profile [(r, z)] that starts and ends on the
    axis (r = 0: the poles), its segments cut to `step` metres at most; returns (vertices,
    faces) outward for a profile going up the outside (counter-clockwise in the r-z half
    plane)."""
    prof = [np.asarray(profile[0], float)]
    for q in np.asarray(profile[1:], float):
        k = int(np.ceil(np.linalg.norm(q - prof[-1]) / step))
        prof += [prof[-1] + (q - prof[-1]) * t for t in np.arange(1, k + 1) / k]
    prof = np.array(prof)
    assert prof[0, 0] == 0 and prof[-1, 0] == 0
    inner = prof[1:-1]
    a = np.linspace(0, 2 * np.pi, seg, endpoint=False)
    ring = np.stack([inner[:, :1] * np.cos(a), inner[:, :1] * np.sin(a),
                     np.repeat(inner[:, 1:], seg, 1)], -1).reshape(-1, 3)
    v = np.vstack([[0, 0, prof[0, 1]], ring, [0, 0, prof[-1, 1]]])
    k = len(inner)
    top = 1 + k * seg
    f = []
    for j in range(seg):
        j1 = (j + 1) % seg
        f.append((0, 1 + j1, 1 + j))
        for i in range(k - 1):
            a0, a1 = 1 + i * seg + j, 1 + i * seg + j1
            b0, b1 = a0 + seg, a1 + seg
            f += [(a0, a1, b1), (a0, b1, b0)]
        f.append((top, 1 + (k - 1) * seg + j, 1 + (k - 1) * seg + j1))
    return v, np.array(f)


def frame_to(v, p0, p1):
    """Maps local points (z along the axis from 0 to |p1 - p0|) onto the segment p0 -> p1."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    z = (p1 - p0) / np.linalg.norm(p1 - p0)
    x = np.cross(z, [0, 0, 1] if abs(z[2]) < 0.9 else [1, 0, 0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return p0 + v @ np.stack([x, y, z])


def capsule(p0, p1, r, seg=24):
    """Closed capsule: the segment p0 -> p1 swept by a sphere of radius r."""
    length = np.linalg.norm(np.subtract(p1, p0))
    t = np.linspace(-np.pi / 2, 0, seg // 2 + 1)
    prof = [(r * np.cos(s), r * np.sin(s)) for s in t]
    prof += [(r * np.cos(s), length + r * np.sin(-s)) for s in t[::-1]]
    prof[0], prof[-1] = (0, -r), (0, length + r)
    v, f = revolve(prof, seg)
    return frame_to(v, p0, p1), f


def ellipsoid(c, radii, seg=32):
    t = np.linspace(-np.pi / 2, np.pi / 2, seg // 2 + 1)
    v, f = revolve([(0 if k in (0, len(t) - 1) else np.cos(s), np.sin(s))
                    for k, s in enumerate(t)], seg)
    return np.asarray(c) + v * np.asarray(radii), f


def box(lo, hi, step=0.015):
    """Closed box, its faces split (midpoint subdivision) to edges of about `step` metres or
    less, so that dropping the faces inside another part leaves the rest of a face."""
    import open3d as o3d
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = o3d.geometry.TriangleMesh.create_box(*(hi - lo))
    k = int(np.ceil(np.log2(max(1.0, (hi - lo).max() / step))))
    if k:
        m = m.subdivide_midpoint(number_of_iterations=k)
    return np.asarray(m.vertices) + lo, np.asarray(m.triangles)


def tube_arc(centre, radius, r, a0, a1, plane=(0, 2), seg=16, steps=24):
    """Closed tube of radius r along an arc (radius `radius` about `centre`, angles a0..a1 in
    the coordinate plane `plane`), its two ends capped."""
    c = np.asarray(centre, float)
    u, w = np.eye(3)[plane[0]], np.eye(3)[plane[1]]
    n = np.cross(u, w)
    ang = np.linspace(a0, a1, steps)
    b = np.linspace(0, 2 * np.pi, seg, endpoint=False)
    v = []
    for t in ang:
        d = np.cos(t) * u + np.sin(t) * w
        for s in b:
            v.append(c + (radius + r * np.cos(s)) * d + r * np.sin(s) * n)
    f = []
    for i in range(steps - 1):
        for j in range(seg):
            a, a1_ = i * seg + j, i * seg + (j + 1) % seg
            f += [(a, a1_ + seg, a1_), (a, a + seg, a1_ + seg)]
    e0, e1 = len(v), len(v) + 1
    v += [c + radius * (np.cos(a0) * u + np.sin(a0) * w), c + radius * (np.cos(a1) * u + np.sin(a1) * w)]
    last = (steps - 1) * seg
    for j in range(seg):
        f += [(e0, j, (j + 1) % seg), (e1, last + (j + 1) % seg, last + j)]
    return np.array(v), np.array(f)


# --------------------------------------------------------------------------- procedural objects


def cellist():
    """Seated cellist on a chair standing on the floor (z = 0), facing -y; metres."""
    m = Mesh()
    # Chair: seat 0.44 x 0.42 at 0.45 m, four legs from the floor, a backrest.
    for x in (-0.2, 0.18):
        for y in (-0.2, 0.18):
            m.add(*box((x, y, 0.0), (x + 0.03, y + 0.03, 0.45)))
    m.add(*box((-0.22, -0.22, 0.45), (0.22, 0.22, 0.49)))
    m.add(*box((-0.2, 0.18, 0.49), (0.2, 0.21, 0.9)))
    # Figure: pelvis, torso, head, neck; thighs on the seat, shins to the floor, feet.
    m.add(*ellipsoid((0, 0.05, 0.57), (0.17, 0.12, 0.09)))
    m.add(*capsule((0, 0.07, 0.6), (0, 0.09, 0.95), 0.14))
    m.add(*capsule((0, 0.08, 1.05), (0, 0.08, 1.13), 0.05))
    m.add(*ellipsoid((0, 0.06, 1.23), (0.09, 0.1, 0.12)))
    for s in (-1, 1):
        knee = (s * 0.2, -0.36, 0.55)
        m.add(*capsule((s * 0.09, 0.02, 0.56), knee, 0.075))
        ankle = (s * 0.22, -0.42, 0.09)
        m.add(*capsule(knee, ankle, 0.055))
        m.add(*box((s * 0.22 - 0.045, -0.56, 0.0), (s * 0.22 + 0.045, -0.36, 0.07)))
    # Cello between the knees: two-lobed body, neck with scroll, end pin to the floor.
    m.add(*ellipsoid((0, -0.45, 0.42), (0.2, 0.11, 0.2)))
    m.add(*ellipsoid((0, -0.43, 0.72), (0.17, 0.1, 0.17)))
    m.add(*box((-0.025, -0.44, 0.85), (0.025, -0.41, 1.25)))
    m.add(*ellipsoid((0, -0.43, 1.28), (0.035, 0.035, 0.05)))
    m.add(*capsule((0, -0.45, 0.22), (0, -0.47, 0.005), 0.006))
    # Arms: left hand on the neck, right hand holding the bow across the strings.
    lh, rh = (-0.04, -0.42, 1.05), (0.42, -0.45, 0.62)
    for sh, el, hand in (((-0.17, 0.08, 1.0), (-0.3, -0.15, 0.95), lh),
                         ((0.17, 0.08, 1.0), (0.3, -0.2, 0.8), rh)):
        m.add(*capsule(sh, el, 0.045))
        m.add(*capsule(el, hand, 0.038))
        m.add(*ellipsoid(hand, (0.045, 0.03, 0.05)))
    # Bow: 0.7 m stick, 5 mm radius, from the right hand across the cello to the left.
    m.add(*capsule((0.45, -0.47, 0.62), (-0.24, -0.58, 0.56), 0.005, seg=12))
    return m.arrays()


def jug():
    """Jug 0.30 m tall: outer radius 0.1 m (a waist), 6 mm wall, 10 mm bottom; a handle tube of
    12 mm radius on its side (its ends inside the wall)."""
    outer = [(0.1, 0.0), (0.11, 0.08), (0.1, 0.2), (0.085, 0.27), (0.095, 0.3)]
    inner = [(r - 0.006, z) for r, z in outer][::-1]
    prof = [(0, 0)] + outer + [(0.089, 0.3)] + inner[1:-1] + [(0.094, 0.01), (0, 0.01)]
    # the inside: from the rim down to the bottom (10 mm thick), then the axis.
    m = Mesh().add(*revolve(prof, 64))
    m.add(*tube_arc((0.08, 0, 0.16), 0.08, 0.012, -np.pi / 2 + 0.25, np.pi / 2 - 0.25, (0, 2)))
    return m.arrays()


def puppet():
    """Marionette-like figure (about 0.56 m before scaling; rgbd-synth scales to 0.28 m)."""
    m = Mesh()
    m.add(*revolve([(0, 0.04), (0.14, 0.04), (0.1, 0.2), (0.05, 0.36), (0, 0.36)], 48))  # cloth
    m.add(*ellipsoid((0, 0, 0.42), (0.07, 0.07, 0.075)))  # head
    m.add(*revolve([(0, 0.47), (0.075, 0.47), (0.0, 0.56)], 32))  # pointed hat (apex pole)
    m.add(*ellipsoid((0, -0.065, 0.42), (0.015, 0.015, 0.015)))  # nose
    for s in (-1, 1):
        el = (s * 0.14, -0.02, 0.26)
        m.add(*capsule((s * 0.05, 0, 0.34), el, 0.014))
        m.add(*capsule(el, (s * 0.2, -0.06, 0.34), 0.012))
        m.add(*ellipsoid((s * 0.21, -0.07, 0.355), (0.022, 0.02, 0.025)))
        m.add(*ellipsoid((s * 0.05, -0.05, 0.02), (0.035, 0.06, 0.02)))  # feet
        m.add(*capsule((s * 0.05, -0.02, 0.04), (s * 0.05, -0.02, 0.1), 0.02))  # legs
    return m.arrays()


PROCEDURAL = {"cellist": cellist, "jug": jug, "puppet": puppet}


# --------------------------------------------------------------------------- output


def write_off(path, v, f):
    with open(path, "w") as o:
        o.write(f"OFF\n{len(v)} {len(f)} 0\n")
        np.savetxt(o, v, fmt="%.6f")
        np.savetxt(o, np.hstack([np.full((len(f), 1), 3), f]), fmt="%d")


def boundary_edges(f):
    """Edges used by one face only (0 for a closed surface)."""
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1)
    _, c = np.unique(e, axis=0, return_counts=True)
    return int((c == 1).sum())


def cap_holes(v, f):
    """Closes every boundary loop of (v, f) with a fan around the loop's centroid, oriented
    with its faces (a bust's neck cut becomes a flat-ish base, as the sculpted busts have one:
    otherwise the closed reconstruction's base would count as invented against an open truth);
    returns (vertices, faces, number of loops)."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = lambda a, b: a * len(v) + b  # noqa: E731
    directed = set(key(a, b) for a, b in e)
    nxt = {}
    for a, b in e:
        if key(b, a) not in directed:  # boundary edge a -> b: the cap runs b -> a
            nxt[b] = a
    v, f, loops = list(v), list(f), 0
    while nxt:
        start = next(iter(nxt))
        loop, x = [start], nxt.pop(start)
        while x != start and x in nxt:
            loop.append(x)
            x = nxt.pop(x)
        c = len(v)
        v.append(np.mean([v[i] for i in loop], 0))
        f += [(loop[i], loop[(i + 1) % len(loop)], c) for i in range(len(loop))]
        loops += 1
    return np.array(v), np.array(f), loops


def make(out, names=None, shared=SHARED):
    """Writes the set into `out` (the busts from `shared`, the meshes folder of ../shared/data);
    returns the objects.json entries (absent sources left out)."""
    os.makedirs(out, exist_ok=True)
    entries = []
    tar = None
    for name, src, rel, kind, up, height, extra, scene, note in CATALOGUE:
        if names and name not in names:
            continue
        e = {"name": name, "kind": kind, "scene": scene}
        if src == "shared":
            path = os.path.join(shared, rel)
            if not os.path.exists(path):
                print(f"objects: leaving out {name}: {path} is absent", file=sys.stderr)
                continue
            file = name + os.path.splitext(rel)[1]
            shutil.copyfile(path, os.path.join(out, file))
            e["provenance"] = f"../shared/data/meshes/{rel}; {note}"
        elif src == "cgal":
            if tar is None:
                if not os.path.exists(CGAL_DATA):
                    sys.exit(f"objects: {CGAL_DATA} is absent (apt-get install libcgal-dev)")
                tar = tarfile.open(CGAL_DATA)
            file = name + ".off"
            with open(os.path.join(out, file), "wb") as o:
                o.write(tar.extractfile(f"data/meshes/{rel}").read())
            e["provenance"] = CGAL + rel + "; " + note
            import open3d as o3d
            m = o3d.io.read_triangle_mesh(os.path.join(out, file))
            f = np.asarray(m.triangles)
            if boundary_edges(f):
                v, f, loops = cap_holes(np.asarray(m.vertices), f)
                write_off(os.path.join(out, file), v, f)
                e["provenance"] += (f"; its {loops} boundary loop(s) capped by a fan (objects.py "
                                    f"cap_holes): {boundary_edges(f)} boundary edges left")
        else:
            v, f = PROCEDURAL[name]()
            file = name + ".off"
            write_off(os.path.join(out, file), v, f)
            if height is None:
                height = round(float(np.ptp(v[:, 2])), 4)
            e["provenance"] = (f"procedural (objects.py {name}()): {note}; {len(v)} vertices, "
                               f"{len(f)} faces, {boundary_edges(f)} boundary edges (the "
                               f"seams of the union of closed parts)")
        e["file"] = file
        e["synth"] = ["--up", up, "--height-m", f"{height:g}"] + extra
        e["rig"] = "turntable" if "turntable" in extra else "ring"
        entries.append(e)
    with open(os.path.join(out, "objects.json"), "w") as o:
        json.dump({"objects": entries}, o, indent=1)
    return entries


def load(folder):
    """The objects.json of a folder made by make(): {name: entry with "path"}."""
    p = os.path.join(folder, "objects.json")
    if not os.path.exists(p):
        sys.exit(f"objects: {p} is absent (make it: objects.py --out {folder})")
    out = {}
    for e in json.load(open(p))["objects"]:
        out[e["name"]] = dict(e, path=os.path.join(folder, e["file"]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="folder to write the meshes and objects.json")
    ap.add_argument("--objects", default="", help="comma list of names (default: all)")
    ap.add_argument("--shared", default=SHARED,
                    help="the meshes folder of ../shared/data (default: beside the checkout)")
    a = ap.parse_args()
    names = [x for x in a.objects.split(",") if x]
    known = {c[0] for c in CATALOGUE}
    for n in names:
        if n not in known:
            sys.exit(f"objects: unknown object {n} ({', '.join(sorted(known))})")
    for e in make(a.out, names, a.shared):
        print(f"{e['name']:16s} {e['kind']:9s} {e['file']:22s} {' '.join(e['synth'] + e['scene'])}")


if __name__ == "__main__":
    main()
