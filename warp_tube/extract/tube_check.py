"""Does an extraction need a second look? Warnings, in the user's terms, beside the tube-likeness
check of :mod:`warp_tube.extract.tubelike` (length against radius, closed cross-sections, the rest
surface's fit), which the extraction itself runs.

Extraction finds a centerline in any closed or open surface, so a blob (a sphere), a mesh with too
few vertices to measure the fit, or a broken mesh still gives hubs and spokes. These checks look at
the result and say what is suspicious and what to do:

- *fit not measurable*: no mesh vertex lies away from the ends (e.g. a plain cylinder, whose only
  vertices are its two end rings), so the automatic hub count could not converge;
- *over-resolved*: the automatic hub count went past :data:`MAX_HUBS_PER_RADIUS` hubs per mean
  radius (it stops at its limit when the surface cannot be matched);
- *missed spokes*: more than :data:`MISSED_FRACTION` of the spoke rays hit nothing (unless the
  sections are too flat, :mod:`warp_tube.extract.flat`, which the extraction's own warning says);
- *a large side branch*: a branch left out is at least :data:`LARGE_BRANCH` of the tube's length
  (a Y or a tree: the tube follows the longest route between the mesh's ends, which may not be
  the one wanted);
- *an opening in the wall*: an open loop that is not an end and lies within the tube's radius (a
  branch cut flush, a leak of the segmentation); the tube is kept across it, and the simulated
  surface closes it.
"""

from __future__ import annotations

import math

from .flat import flat_warning
from .wording import counted

__all__ = ["tube_warnings", "summary_line", "size_warning", "check_size"]

MAX_HUBS_PER_RADIUS = 10.0
MISSED_FRACTION = 0.10
#: a side branch left out at least this fraction of the tube's length is warned of
LARGE_BRANCH = 0.25
#: ``--hubs`` above this gets a warning with the size of what will be written.
LARGE_HUBS = 20_000
#: characters per spoke length and per hub written to a .usda scene (measured on written scenes).
USDA_CHARS_PER_SPOKE = 13
USDA_CHARS_PER_HUB = 60
#: ``--hubs`` above this is refused: a million centerline points is far past any tube's needs
#: (a hub per mean radius is the default) and an extraction of hours.
MAX_HUBS = 1_000_000
#: memory an extraction takes per spoke [bytes], at its peak: the spokes' rays, lengths and rest
#: rings, the scene's text, and the simulation that sizes the push; ``hubs x spokes`` needing more
#: than the memory available is refused before any work.
BYTES_PER_SPOKE = 2048


def tube_warnings(tube, fidelity=None, automatic_hubs: bool = True, units: str = "m") -> list[str]:
    """Warnings about an extracted tube (see the module docstring); empty when it looks fine.

    Args:
        tube: the :class:`~warp_tube.extract.pipeline.ExtractedTube` (lengths in its mesh units).
        fidelity: its :class:`~warp_tube.extract.fidelity.Fidelity`, or None if not measured.
        automatic_hubs: the hub count was chosen by the extraction (no ``--hubs``).
        units: the name of the tube's length unit, for the messages.
    """
    out = []
    r = float(tube.radius.mean())
    length = tube.length
    if fidelity is not None and fidelity.to_surface.counted == 0:
        if tube.length <= tube.ends[0].radius + tube.ends[1].radius:
            # (the fit leaves out the mesh within one end radius of either end: here all of it)
            out.append(
                f"the fit of the rebuilt surface could not be measured: the tube is {tube.length:.3g} {units} long between "
                f"its end hubs, no more than its two end radii ({tube.ends[0].radius:.3g} and {tube.ends[1].radius:.3g} "
                f"{units}), within which the fit leaves the mesh out"
            )
        else:
            out.append(
                "the fit of the rebuilt surface could not be measured: no mesh vertex lies away from the tube's ends "
                "(a mesh with vertices only at its end rings, such as a plain cylinder, has none); subdivide the mesh "
                "along its length" + (" or pass --hubs N" if automatic_hubs else "")
            )
    per_radius = (tube.hubs - 1) * r / length if length > 0 else math.inf
    if automatic_hubs and per_radius > MAX_HUBS_PER_RADIUS:
        out.append(
            f"{tube.hubs} hubs for a tube {length:.3g} {units} long and {r:.3g} {units} in radius ({per_radius:.0f} per radius, where "
            f"one or two suffice): the surface could not be matched with fewer; check the mesh, or pass --hubs "
            f"{max(8, round(length / r) + 1)}"
        )
    rays = tube.hubs * tube.spokes
    too_flat = flat_warning(getattr(tube, "aspect", 1.0)) is not None  # (the tube's own warning says so)
    if rays and tube.missed_spokes > MISSED_FRACTION * rays and not too_flat:
        out.append(
            f"{tube.missed_spokes} of {rays} spoke rays ({tube.missed_spokes / rays:.0%}) hit no wall and were "
            "filled in from neighbouring hubs: the mesh has large openings or is not a tube"
        )
    large = [(j, b) for j, b in tube.branches if length > 0 and b >= LARGE_BRANCH * length]
    if large:
        j, b = max(large, key=lambda jb: jb[1])
        more = f" ({len(large) - 1} more as large)" if len(large) > 1 else ""
        out.append(
            f"a side branch {b:.3g} {units} long ({b / length:.0%} of the tube's {length:.3g} {units}) leaves it at hub {j} "
            f"and is left out{more}: the tube follows the longest route between the mesh's ends; to simulate another "
            "route, cut the mesh to it"
        )
    holes = [o for o in getattr(tube, "openings", []) if o.kind == "wall"]
    if holes:
        where = ", ".join(f"{2.0 * o.radius:.3g} {units} across at hub {o.hub}" for o in holes[:5])
        more = f" and {len(holes) - 5} more" if len(holes) > 5 else ""
        out.append(
            f"{counted(len(holes), 'opening')} in the tube's wall ({where}{more}, of {tube.hubs} hubs): the tube is "
            "kept across and its simulated surface closed there (recorded in customData warptube:openings)"
        )
    return out


def check_size(hubs, spokes) -> None:
    """Refuse (:class:`~warp_tube.scene.spec.SceneError`) a ``--hubs`` over :data:`MAX_HUBS`, or
    ``hubs x spokes`` needing more memory (:data:`BYTES_PER_SPOKE`) than is available now: such an
    extraction would run for hours and end killed by the system."""
    from ..runtime.memory import available_memory
    from ..scene.spec import SceneError

    if hubs is None or not isinstance(hubs, int) or not isinstance(spokes, int):
        return  # (the automatic count, or a value the extraction itself refuses)
    if hubs > MAX_HUBS:
        raise SceneError(f"--hubs {hubs:,}: expected at most {MAX_HUBS:,}; without --hubs the hub count follows the tube's "
                         "length and radius (a hub per mean radius)")  # fmt: skip
    need, free = hubs * max(spokes, 1) * BYTES_PER_SPOKE, available_memory()
    if free is not None and need > free:
        raise SceneError(f"--hubs {hubs:,} x --spokes {spokes}: {hubs * spokes:,} spokes need about {need / 1e9:.1f} GB of "
                         f"memory to extract, more than the {free / 1e9:.1f} GB available; pass fewer hubs (without --hubs "
                         "the hub count follows the tube's length and radius)")  # fmt: skip


def size_warning(hubs: int, spokes: int) -> str | None:
    """A warning for ``--hubs`` so large that extraction and the written scene get big, or None."""
    if hubs is None or hubs <= LARGE_HUBS:
        return None
    mb = (hubs * spokes * USDA_CHARS_PER_SPOKE + hubs * USDA_CHARS_PER_HUB) / 1e6
    return (
        f"--hubs {hubs:,}: {hubs * spokes:,} spokes to cast and write (a .usda scene of about {mb:,.0f} MB); "
        "this takes minutes and the scene will simulate slowly. Without --hubs the hub count follows the "
        "tube's length and radius"
    )


def side_branches(count: int) -> str:
    """``1 side branch``, ``3 side branches``."""
    return counted(count, "side branch")


def summary_line(tube, fidelity, output: str, units: str = "m") -> str:
    """One line about an extraction: hubs, length (tip to tip), radius range, ends, branches, fit (of
    a closed ring: on the part kept, with how much of the ring was left out)."""
    ends = "/".join(e.kind for e in tube.ends)
    ring = tube.ring
    if ring is not None:
        ends += f" of a closed ring cut open ({ring.left_out:.0%} of its surface left out)"
    fit = "fit not measured"
    if fidelity is not None:
        fit = (
            f"surface within {fidelity.mean:.1%} (mean) / {fidelity.p99:.1%} (99th percentile) of the radius, "
            f"both ways{'' if ring is None else ', on the part kept'}"
            if fidelity.to_surface.counted
            else "fit not measurable"
        )
    span = f" ({tube.length:.4g} between its end hubs)" if not tube.caps and tube.length < 0.95 * tube.tip_to_tip else ""
    return (
        f"{output}: {tube.hubs} hubs x {tube.spokes} spokes, {tube.tip_to_tip:.4g} {units} long{span}, radius "
        f"{tube.radius.min():.3g}-{tube.radius.max():.3g} {units}, ends {ends}, {side_branches(len(tube.branches))} "
        f"left out, {fit}"
    )
