"""The Open3D pipeline of the peer comparisons (docs/method.md, the Open3D 0.16 chain),
shared by the validation scripts that compare with Open3D (person_vs_open3d.py, ablation.py,
icp_vs_open3d.py, measure_align.py): per view statistical outlier removal and a down-sampled copy
with normals, pairwise multi-scale point-to-plane ICP, the pose graph (register_ring: the ring of
pairs from the identity or from given poses), the merged world-frame cloud and Screened Poisson;
and TSDF fusion of depth images with marching cubes (tsdf_mesh). Open3D is imported by each
function, so the module loads without it."""
import numpy as np

from rgbd_stream import rgb_of, xyz_of

# Coarse to fine: (max correspondence distance m, iterations) of the pairwise ICP.
ICP_SCALES = [(0.048, 40), (0.024, 40), (0.012, 40), (0.006, 30)]


def o3d_cloud(doc):
    """Open3D cloud of a document's points, with its colours when it has them."""
    import open3d as o3d
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz_of(doc)))
    rgb = rgb_of(doc)
    if rgb is not None:
        pc.colors = o3d.utility.Vector3dVector(rgb)
    return pc


def downsampled_with_normals(pc, voxel):
    """A voxel-down-sampled copy of a sensor-frame cloud with normals (hybrid radius 4 voxels,
    30 neighbours) turned towards the camera at the origin."""
    import open3d as o3d
    s = pc.voxel_down_sample(voxel)
    s.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=4 * voxel, max_nn=30))
    s.orient_normals_towards_camera_location(np.zeros(3))
    return s


def o3d_view_cloud(doc, voxel):
    """Open3D cloud of one sensor-frame document: voxel-down-sampled, normals (hybrid radius 4
    voxels, 30 neighbours) turned towards the camera at the origin, colours when present."""
    return downsampled_with_normals(o3d_cloud(doc), voxel)


def prepare_views(docs, voxel):
    """Per sensor-frame document: statistical outlier removal (20 neighbours, 2 sigma) and the
    down-sampled copy with normals for the registration. Returns (full clouds, small clouds)."""
    full, small = [], []
    for doc in docs:
        pc, _ = o3d_cloud(doc).remove_statistical_outlier(nb_neighbors=20, std_ratio=2.0)
        full.append(pc)
        small.append(downsampled_with_normals(pc, voxel))
    return full, small


def pair_icp(small, i, j, start):
    """Multi-scale point-to-plane ICP of view j onto view i from `start` (4x4 target_from_source,
    ICP_SCALES); returns (transformation, information matrix at 12 mm)."""
    import open3d as o3d
    reg = o3d.pipelines.registration
    t = start
    for dist, iterations in ICP_SCALES:
        t = reg.registration_icp(small[j], small[i], dist, t,
                                 reg.TransformationEstimationPointToPlane(),
                                 reg.ICPConvergenceCriteria(1e-6, 1e-6, iterations)).transformation
    return t, reg.get_information_matrix_from_point_clouds(small[j], small[i], 0.012, t)


def register_ring(small, starts=None):
    """Consecutive pairs (view j = i + 1 onto view i) and, with more than two views, the
    loop-closing pair (0 onto n-1) by pair_icp, then the pose graph (optimise; the closing edge
    uncertain). `starts`: 4x4 world_from_sensor per view (e.g. the capture's poses): each pair
    starts from inv(starts[i]) @ starts[j] and the graph's nodes are the starts; None: each pair
    starts from the identity and the nodes are the pair results chained from view 0. Returns
    (world_from_sensor per view after the pose graph, pair results [target_from_source] in
    pair order, the last one the closing pair)."""
    import open3d as o3d
    reg = o3d.pipelines.registration
    n = len(small)
    graph = reg.PoseGraph()
    chained = [np.eye(4) if starts is None else np.asarray(starts[0])]
    graph.nodes.append(reg.PoseGraphNode(chained[0]))
    edges = []
    for i in range(n if n > 2 else n - 1):
        j = (i + 1) % n
        start = np.eye(4) if starts is None else np.linalg.inv(starts[i]) @ starts[j]
        tr, info = pair_icp(small, i, j, start)
        if j != 0:
            chained.append(chained[-1] @ tr if starts is None else np.asarray(starts[j]))
            graph.nodes.append(reg.PoseGraphNode(chained[-1]))
        graph.edges.append(reg.PoseGraphEdge(j, i, tr, info, uncertain=(j == 0)))
        edges.append(tr)
    optimise(graph)
    return [np.asarray(node.pose) for node in graph.nodes], edges


def tsdf_mesh(frames, poses, voxel=0.004, trunc_voxels=4.0, depth_trunc=3.0):
    """Open3D's TSDF fusion: a ScalableTSDFVolume (voxel `voxel` m, sdf_trunc trunc_voxels
    voxels, colour RGB8) integrating every frame at its pose, then marching cubes
    (extract_triangle_mesh). `frames`: per view a dict with `color` (8-bit RGB, H x W x 3),
    `depth` (uint16, H x W, registered to the colour image, 0 = no depth), `depth_scale`
    (values per metre) and `intrinsics` (w, h, fx, fy, cx, cy); poses: 4x4 world_from_sensor.
    Returns (mesh, seconds integrating, seconds extracting)."""
    import time
    import open3d as o3d
    vol = o3d.pipelines.integration.ScalableTSDFVolume(
        voxel_length=voxel, sdf_trunc=trunc_voxels * voxel,
        color_type=o3d.pipelines.integration.TSDFVolumeColorType.RGB8)
    t0 = time.perf_counter()
    for f, pose in zip(frames, poses):
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(np.ascontiguousarray(f["color"])),
            o3d.geometry.Image(np.ascontiguousarray(f["depth"])), depth_scale=f["depth_scale"],
            depth_trunc=depth_trunc, convert_rgb_to_intensity=False)
        vol.integrate(rgbd, o3d.camera.PinholeCameraIntrinsic(*f["intrinsics"]),
                      np.linalg.inv(pose))
    t1 = time.perf_counter()
    mesh = vol.extract_triangle_mesh()
    return mesh, t1 - t0, time.perf_counter() - t1


def merge_views(full, poses):
    """The views in the world frame, each with normals (radius 10 mm, 30 neighbours) turned
    towards its camera, merged, down-sampled to 2 mm and cleaned (20 neighbours, 2 sigma)."""
    import open3d as o3d
    merged = o3d.geometry.PointCloud()
    for pc, pose in zip(full, poses):
        w = o3d.geometry.PointCloud(pc)
        w.transform(pose)
        w.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=0.01, max_nn=30))
        w.orient_normals_towards_camera_location(pose[:3, 3])
        merged += w
    merged = merged.voxel_down_sample(0.002)
    merged, _ = merged.remove_statistical_outlier(nb_neighbors=20, std_ratio=2.0)
    merged.normalize_normals()
    return merged


def screened_poisson(merged, depth):
    """Open3D's Screened Poisson (width 0, scale 1.1, no linear fit); returns (mesh, densities)."""
    import open3d as o3d
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            merged, depth=depth, width=0, scale=1.1, linear_fit=False)
    return mesh, np.asarray(dens)


def optimise(graph):
    """Open3D's pose graph (the peer pipeline of docs/method.md): Levenberg-Marquardt, edge
    prune 0.25, node 0 fixed."""
    import open3d as o3d
    reg = o3d.pipelines.registration
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        reg.global_optimization(graph, reg.GlobalOptimizationLevenbergMarquardt(),
                                reg.GlobalOptimizationConvergenceCriteria(),
                                reg.GlobalOptimizationOption(max_correspondence_distance=0.012,
                                                             edge_prune_threshold=0.25,
                                                             reference_node=0))


# Open3D 0.16's multi-threaded Screened Poisson crashes now and then (SIGSEGV, at times SIGABRT):
# a race in its solver (Open3D issue 6828, PoissonRecon issue 298). Run the peer in a child
# process and run it again when a signal kills the child, so that one crash does not end a
# benchmark of many minutes. The same threads again: the race is rare, and fewer threads would
# make the peer slower than it is.
CRASH_RETRIES = 2


def _child(conn, fn, args):
    conn.send(fn(*args))
    conn.close()


def run_in_child(fn, *args, what="the Open3D peer"):
    """fn(*args) in a fresh (spawned) Python process; returns its (picklable) result. Runs it
    again, with a warning on stderr, when a signal kills the child (CRASH_RETRIES times at most);
    exits the script when it still dies or when it fails otherwise."""
    import multiprocessing
    import sys
    ctx = multiprocessing.get_context("spawn")
    for attempt in range(CRASH_RETRIES + 1):
        parent, child = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=_child, args=(child, fn, args))
        proc.start()
        child.close()
        try:
            result = parent.recv()
        except EOFError:  # the child died before it sent anything
            result = None
        proc.join()
        if proc.exitcode == 0:
            return result
        if proc.exitcode is not None and proc.exitcode < 0 and attempt < CRASH_RETRIES:
            print(f"warning: {what} was killed by signal {-proc.exitcode} (Open3D's Poisson "
                  "race, Open3D issue 6828); running it again", file=sys.stderr, flush=True)
            continue
        how = f"killed by signal {-proc.exitcode}" if proc.exitcode < 0 else \
            f"exit code {proc.exitcode}"
        sys.exit(f"{what} failed ({how})")
