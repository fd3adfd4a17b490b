"""Whether an extracted mesh is a tube, and whether its hubs rebuild it well enough.

Three checks on the mesh (their warnings start with :data:`NOT_A_TUBE`, and ``warp-tube extract
--strict`` refuses the mesh on them):

- a closed ring (a torus: watertight, ``V - E + F = 0``, :mod:`warp_tube.extract.closed_ring`) has
  no ends: the tube is cut open where the warning says and leaves the rest of the ring out;
- length against radius: the axis from tip to tip must be at least :data:`MIN_LENGTH_RADII` mean
  radii long (a sphere or a blob gives about two);
- cross-sections that are single closed loops: at most :data:`MAX_OPEN_SECTIONS` of the interior
  hubs may have a ray in their ring plane that leaves the tube through an opening of the mesh
  (:func:`warp_tube.extract.sections.open_rays`): a cylinder with a face missing along its length,
  or a sheet, fails this; a vessel with a few openings where branches were cut flush passes;
- most of the mesh on the tube: at most :data:`MAX_LEFT_OUT` of the mesh's vertices may lie off
  its rings (beyond its ends, or nearer a side branch than the axis; :func:`~warp_tube.extract.fidelity.measured_vertices`):
  a closed plate gives a thin "tube" across it and leaves 99% out; a vessel leaves out 3-23% (its
  ends and branches), a tube five radii long about half (its ends). Where no vertex could be
  measured against the rings (a plain capsule's lie at its ends, and so do a thin plate's), the tube
  must hold at least :data:`MIN_VOLUME_HELD` of the volume the mesh encloses instead.

Sections flatter than :data:`~warp_tube.extract.flat.MAX_ASPECT` are warned of as too flat, with
their measured aspect. One check on the result: the rest surface the simulator builds (:mod:`warp_tube.extract.fidelity`)
must lie within :data:`~warp_tube.extract.fidelity.FIDELITY_BOUNDS` of the mesh both ways; if not,
the warning names the figures, and with a given hub count the hub spacing it used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .fidelity import FIDELITY_BOUNDS
from .flat import ALIGN_ASPECT, flat_warning
from .wording import counted

if TYPE_CHECKING:
    from .pipeline import ExtractedTube

__all__ = ["NOT_A_TUBE", "MIN_LENGTH_RADII", "MAX_OPEN_SECTIONS", "check", "ring_warning"]

NOT_A_TUBE = "not tube-like"
MIN_LENGTH_RADII = 4.0
"""Least length of a tube from tip to tip, in mean radii."""
MAX_OPEN_SECTIONS = 0.25
"""Largest fraction of interior hubs whose ring is not a closed loop of the tube's wall."""
MAX_LEFT_OUT = 0.9
"""Largest fraction of the mesh's vertices off the tube's rings (beyond its ends, in side branches)."""


def check(tube: ExtractedTube, open_rays: np.ndarray, *, hubs_given: bool, mesh_volume: float = 0.0,
          strict: bool = False) -> list[str]:
    """Warnings about ``tube`` (see the module); empty when it passes.

    Args:
        tube: the extracted tube (its fidelity filled in).
        open_rays: which rays of each hub's ring leave through an opening, bool (hubs, rays).
        hubs_given: whether the hub count came from the caller (``--hubs``).
        mesh_volume: the volume the mesh encloses (its openings closed; its inside voxels') [mesh units^3],
            or 0 if unknown.
        strict: the warnings refuse the mesh (``--strict``): a ring is said as what the tube would do.
    """
    out = [] if tube.ring is None else [ring_warning(tube.ring, refused=strict)]
    radius = float(tube.spoke_lengths.mean())
    reach = tube.tip_to_tip
    if reach < MIN_LENGTH_RADII * radius:
        out.append(
            f"{NOT_A_TUBE}: {np.floor(10.0 * reach / radius) / 10.0:.1f} mean radii long from end to end (mean "
            f"radius {radius:.4g}); "  # rounded down: a length just short of the bound never reads as the bound
            f"a tube is at least {MIN_LENGTH_RADII:g}"
        )
    inner = np.asarray(open_rays)[1:-1]
    if len(inner):
        open_hubs = int(inner.any(axis=1).sum())
        if open_hubs > MAX_OPEN_SECTIONS * len(inner):
            out.append(
                f"{NOT_A_TUBE}: the cross-sections at {open_hubs} of {counted(len(inner), 'hub')} are not closed "
                "loops of its wall (rays across them leave through an opening of the mesh)"
            )
    fid = tube.fidelity
    if fid is not None and fid.to_surface.counted:  # (none counted: the fit's own warning says so)
        off = fid.to_surface.left_out / (fid.to_surface.counted + fid.to_surface.left_out)
        if off > MAX_LEFT_OUT:
            out.append(
                f"{NOT_A_TUBE}: {np.floor(100.0 * off):.0f}% of the mesh's vertices lie off the tube's rings (beyond its "
                f"ends or in side branches); a tube holds most of its mesh (a sheet or a plate gives a thin tube "
                "across it)"
            )
    if fid is not None and not fid.to_surface.counted and mesh_volume > 0.0:
        # No vertex measured against the rings (a plain capsule's vertices all lie at its ends; so do
        # a plate's, beyond a thin tube across it): the tube's own volume tells them apart.
        held = tube_volume(tube) / mesh_volume
        if held < MIN_VOLUME_HELD:
            out.append(
                f"{NOT_A_TUBE}: the tube holds {100.0 * held:.2g}% of the volume the mesh encloses; a tube holds most "
                "of it (a sheet or a plate gives a thin tube across it)"
            )
    flat = flat_warning(getattr(tube, "aspect", 1.0))
    if flat:
        out.append(flat)
    out += _end_warnings(tube, radius)
    if fid is not None and not fid.within(*FIDELITY_BOUNDS):
        bounds = " / ".join(f"{100 * b:g}" for b in FIDELITY_BOUNDS)
        text = (
            f"the rest surface misses the mesh: mesh to surface {_figures(fid.to_surface)}, surface to mesh "
            f"{_figures(fid.to_input)} of the mean radius (mean / 99th percentile / largest; bounds {bounds} %)"
        )
        aspect = getattr(tube, "aspect", 1.0)
        if aspect > ALIGN_ASPECT and tube.spokes < 32:
            text += f"; flat sections (aspect {aspect:.1f}:1) are followed closer by more spokes: --spokes 32"
        if hubs_given:
            spacing = tube.length / max(tube.hubs - 1, 1) / radius
            text += (
                f"; --hubs {tube.hubs} puts hubs {spacing:.2g} mean radii apart (tortuous tubes need about 0.3): "
                "leave --hubs out to have the count chosen"
            )
        out.append(text)
    return out


#: least fraction of the mesh's volume the tube holds, where no vertex could be measured against its rings
MIN_VOLUME_HELD = 0.1


def tube_volume(tube: ExtractedTube) -> float:
    """The volume of the tube's rings swept along its hubs [mesh units^3]: each hub's section
    (pi x its mean squared spoke length) over the segments beside it."""
    area = np.pi * np.mean(np.asarray(tube.spoke_lengths, dtype=np.float64) ** 2, axis=1)
    seg = np.linalg.norm(np.diff(np.asarray(tube.points, dtype=np.float64), axis=0), axis=1)
    return float(np.sum(0.5 * (area[:-1] + area[1:]) * seg))


#: the ends' rings trimmed back by more than this fraction of the tip-to-tip length are warned of
MAX_TRIMMED = 0.1


def _end_warnings(tube: ExtractedTube, radius: float) -> list[str]:
    """What the simulated tube leaves out at its ends: much of its length trimmed back (the end
    rings kept clear of the cuts, on a short or fat tube). (A rounded end opposite an open one has
    no cap, caps being built where both ends close: its tip, about an end radius, is left out as
    the fit leaves one end radius out at each end; real vessels' blunt ends are so.)"""
    out = []
    trimmed = [e.trimmed for e in tube.ends]
    uncovered = [0.0 if tube.caps else t for t in trimmed]  # (caps reach the rounded tips)
    if sum(uncovered) > MAX_TRIMMED * tube.tip_to_tip:
        out.append(
            f"its end hubs span {tube.length:.4g} of the {tube.tip_to_tip:.4g} from tip to tip: the ends are trimmed back "
            f"by {trimmed[0]:.3g} and {trimmed[1]:.3g} ({trimmed[0] / radius:.2g} and {trimmed[1] / radius:.2g} mean radii; "
            "an end ring stays clear of a cut or an opening), and the simulated surface stops there"
        )
    return out


def _figures(d) -> str:
    """One direction's mean / 99th percentile / largest distance in % of the mean radius, or
    "not measured" where no point was measured (its figures are NaN)."""
    if d.counted == 0:
        return "not measured (no vertex away from the ends)"
    return f"{100 * d.mean:.1f} / {100 * d.p99:.1f} / {100 * d.max:.1f} %"


def ring_warning(ring, refused: bool = False) -> str:
    """The warning for a closed ring (:class:`~warp_tube.extract.closed_ring.RingCut`): where the
    tube cuts it open [mesh units, to 1/1000 of the cuts' distance apart] and how much of its
    surface the tube leaves out: the gap between its two end rings. ``refused``: as ``--strict``
    refuses it (what the tube would do: nothing is written)."""
    cuts = np.asarray(ring.cuts, dtype=np.float64)
    step = 10.0 ** (np.floor(np.log10(max(float(np.linalg.norm(cuts[0] - cuts[1])), 1e-300))) - 3)
    a, b = (", ".join(f"{x:.4g}" for x in np.round(c / step) * step + 0.0) for c in cuts)
    cut, leaves = ("would be cut open", "leave") if refused else ("is cut open", "leaves")
    return (
        f"{NOT_A_TUBE}: a closed ring with no ends (watertight, V - E + F = 0): the tube {cut} at "
        f"({a}) and ({b}) and {leaves} {ring.left_out:.0%} of the ring's surface out (between its two end rings)"
    )
