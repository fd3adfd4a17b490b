"""Mesh queries of centerline extraction: ray casts, inside/outside voxel columns, distances.

Pure functions of arrays on a ``wp.Mesh`` (id passed as ``wp.uint64``); the host side is
:mod:`warp_tube.extract.distance_map` and :mod:`warp_tube.extract.pipeline`. Lengths are in the mesh's units.
"""

import warp as wp


RAY_TWIN_TURN = wp.constant(1.0e-3)
"""Turn of the two twin rays that vouch for a ray's hit (radians); see :func:`cast_rays`."""
RAY_AGREE = wp.constant(1.0e-3)
"""Relative difference of hit distances within which a twin agrees with its ray."""


@wp.func
def ray_hit(mesh_id: wp.uint64, origin: wp.vec3, direction: wp.vec3, max_t: float):
    """Nearest hit distance along ``direction`` from ``origin``, +inf on a miss."""
    q = wp.mesh_query_ray(mesh_id, origin, direction, max_t)
    t = float(wp.inf)
    if q.result:
        t = q.t
    return t


@wp.kernel(enable_backward=False)
def cast_rays(
    # model:
    mesh_id: wp.uint64,
    # in:
    ray_origin_in: wp.array[wp.vec3],
    ray_dir_in: wp.array[wp.vec3],
    max_t: float,
    # out:
    hit_t_out: wp.array[float],
):
    """Nearest hit of each ray: ``hit_t_out[i]`` = distance along the unit ray, or -1 on a miss.

    A ray aimed exactly along an edge or at a vertex may slip between two triangles in float
    arithmetic (and differently on each device): it misses, or hits a farther wall. So each ray has
    two twins turned :data:`RAY_TWIN_TURN` to either side; the ray's own hit stands when a twin
    agrees with it (within :data:`RAY_AGREE` of its distance), otherwise the median of the three
    (misses counted as infinitely far) is taken. ``ray_dir_in`` must hold unit vectors so that
    ``hit_t_out`` and ``max_t`` are distances.
    """
    i = wp.tid()
    o = ray_origin_in[i]
    d = ray_dir_in[i]
    t0 = ray_hit(mesh_id, o, d, max_t)
    axis = wp.vec3(1.0, 0.0, 0.0)
    if wp.abs(d[0]) > 0.6:
        axis = wp.vec3(0.0, 1.0, 0.0)
    u = wp.normalize(wp.cross(d, axis))
    t1 = ray_hit(mesh_id, o, wp.normalize(d + RAY_TWIN_TURN * u), max_t)
    t2 = ray_hit(mesh_id, o, wp.normalize(d - RAY_TWIN_TURN * u), max_t)
    t = t0
    tol = RAY_AGREE * wp.min(t0, max_t)
    if not (wp.abs(t1 - t0) <= tol or wp.abs(t2 - t0) <= tol):
        t = wp.max(wp.min(t0, t1), wp.min(wp.max(t0, t1), t2))  # the median of three
    if t > max_t:
        t = -1.0
    hit_t_out[i] = t


@wp.kernel(enable_backward=False)
def fill_inside_columns(
    # model:
    mesh_id: wp.uint64,
    grid_origin: wp.vec3,
    voxel_size: float,
    ny: int,
    nz: int,
    max_crossings: int,
    # out:
    inside_out: wp.array2d[wp.uint8],
):
    """Inside/outside voxels by crossing parity along +z, one thread per (x, y) column.

    Voxel (ix, iy, iz) has its centre at ``grid_origin + voxel_size * (ix, iy, iz)``; column
    ``c = ix * ny + iy`` is row ``c`` of ``inside_out``, shape (nx * ny, nz), which gets 1 where the
    centre is inside the (closed) mesh and must be zero on entry. Parity needs no face orientation,
    so inward-facing or mixed normals classify the same. Callers offset the grid by an odd fraction
    of a voxel so that columns do not run exactly through mesh edges.
    """
    col = wp.tid()
    ix = col // ny
    iy = col - ix * ny
    h = voxel_size
    x = grid_origin[0] + h * float(ix)
    y = grid_origin[1] + h * float(iy)
    z0 = grid_origin[2]
    up = wp.vec3(0.0, 0.0, 1.0)
    eps = h * 1.0e-4
    z_cur = z0 - h
    z_end = z0 + h * float(nz)
    inside = int(0)
    for _k in range(max_crossings):
        q = wp.mesh_query_ray(mesh_id, wp.vec3(x, y, z_cur), up, z_end - z_cur)
        if not q.result:
            break
        z_hit = z_cur + q.t
        if inside == 1:
            k0 = wp.max(int(wp.ceil((z_cur - z0) / h)), 0)
            k1 = wp.min(int(wp.floor((z_hit - z0) / h)), nz - 1)
            for k in range(k0, k1 + 1):
                inside_out[col, k] = wp.uint8(1)
        inside = 1 - inside
        z_cur = z_hit + eps


@wp.kernel(enable_backward=False)
def closest_distance(
    # model:
    mesh_id: wp.uint64,
    # in:
    point_in: wp.array[wp.vec3],
    max_dist: float,
    # out:
    dist_out: wp.array[float],
):
    """Unsigned distance from each point to the mesh surface; ``max_dist`` where none is closer."""
    i = wp.tid()
    p = point_in[i]
    q = wp.mesh_query_point_no_sign(mesh_id, p, max_dist)
    if q.result:
        dist_out[i] = wp.length(wp.mesh_eval_position(mesh_id, q.face, q.u, q.v) - p)
    else:
        dist_out[i] = max_dist


@wp.kernel(enable_backward=False)
def inner_diameter(
    # model:
    mesh_id: wp.uint64,
    # in:
    point_in: wp.array[wp.vec3],
    normal_in: wp.array[wp.vec3],
    offset: float,
    max_t: float,
    # out:
    hit_t_out: wp.array[float],
):
    """Distance across the solid from surface points, along the normal that points inside.

    ``point_in`` lie on the surface (face centroids) with unit ``normal_in`` of either orientation;
    the side whose point at ``offset`` is inside by ray parity (closed mesh) is taken, so the result
    does not depend on the winding. ``hit_t_out`` = distance to the opposite wall, -1 on a miss.
    """
    i = wp.tid()
    p = point_in[i]
    n = normal_in[i]
    probe = wp.mesh_query_point_sign_parity(mesh_id, p - offset * n, max_t, 3)
    if probe.result and probe.sign >= 0.0:
        n = -n
    q = wp.mesh_query_ray(mesh_id, p - offset * n, -n, max_t)
    if q.result:
        hit_t_out[i] = q.t + offset
    else:
        hit_t_out[i] = -1.0


@wp.kernel(enable_backward=False)
def inside_by_parity(
    # model:
    mesh_id: wp.uint64,
    # in:
    point_in: wp.array[wp.vec3],
    max_dist: float,
    # out:
    inside_out: wp.array[wp.int32],
):
    """1 where a point lies inside the closed mesh by ray parity (three rays, the majority), else 0;
    points farther than ``max_dist`` from the mesh count as outside."""
    i = wp.tid()
    q = wp.mesh_query_point_sign_parity(mesh_id, point_in[i], max_dist, 3)
    if q.result and q.sign < 0.0:
        inside_out[i] = 1
    else:
        inside_out[i] = 0
