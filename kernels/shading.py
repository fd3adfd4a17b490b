"""Shading of a surface for previews (Warp): an orthographic camera's rays against a mesh."""

import warp as wp


@wp.kernel(enable_backward=False)
def shade_orthographic_kernel(
    # model:
    mesh: wp.uint64,
    origin: wp.vec3,
    right: wp.vec3,
    up: wp.vec3,
    view_dir: wp.vec3,
    pixel_size: float,
    max_dist: float,
    # out:
    image_out: wp.array2d[float],
):
    """Lambert shading of a surface seen by an orthographic camera; one thread per pixel.

    Args:
        mesh: ``wp.Mesh`` id of the surface.
        origin: centre of the image plane [length unit], behind the surface along ``view_dir``.
        right, up: unit image axes; ``view_dir``: unit viewing direction.
        pixel_size: pixel pitch on the image plane [length unit].
        max_dist: longest ray [length unit].
        image_out: brightness in [0, 1] of each (row, column) pixel, -1 where no surface is hit;
            row 0 at the top. Two-sided: ``0.2 + 0.8 |n . view_dir|`` (light from the camera).
    """
    row, col = wp.tid()
    rows = image_out.shape[0]
    cols = image_out.shape[1]
    p = (
        origin
        + (float(col) + 0.5 - 0.5 * float(cols)) * pixel_size * right
        + (0.5 * float(rows) - float(row) - 0.5) * pixel_size * up
    )
    q = wp.mesh_query_ray(mesh, p, view_dir, max_dist)
    if q.result:
        n = wp.normalize(q.normal)
        image_out[row, col] = 0.2 + 0.8 * wp.abs(wp.dot(n, view_dir))
    else:
        image_out[row, col] = -1.0
