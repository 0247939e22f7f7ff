"""isotopo: remove small topological handles from isosurfaces of 3-D volumes.

Scans and segmentations turned into surfaces carry hundreds of tiny handles (tunnels) made by
noise. isotopo finds every handle of the isosurface ``volume == iso``, measures each by its two
shortest loops on the surface, and removes those smaller than ``tau`` by changing a thin wall of
samples. Volumes are numpy arrays indexed ``[x, y, z]`` (nibabel's order), in any memory order,
or what :func:`load` returns (lengths and boxes in mm then follow the file's affine; for an
array, pass ``spacing=``).

>>> import isotopo
>>> vol = isotopo.load("brain.nii.gz")                  # doctest: +SKIP
>>> handles = isotopo.analyze(vol, 127.5)                # doctest: +SKIP
>>> out, report = isotopo.simplify(vol, 127.5, 20)      # doctest: +SKIP
>>> print(report.genus_before, "->", report.genus_after)  # doctest: +SKIP
>>> isotopo.save("brain-simplified.nii.gz", out, like=vol)  # doctest: +SKIP

Every function takes the isosurface the same way: ``iso`` (in the array's values), ``inside``
("above": samples greater than iso are inside, as in CT and probability maps; "below" for signed
distance fields) and ``connectivity`` (6: inside samples joined across faces; 26: across faces,
edges and corners). Long calls release the GIL, stop on Ctrl-C with ``KeyboardInterrupt`` and
report progress to ``progress(stage, done, total)``, or to a tqdm bar when tqdm is installed and
the session is interactive (``progress=False``: none).
"""

from __future__ import annotations

import json
import math
import os
import sys
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native

__version__: str = _native.__version__

__all__ = [
    "genus",
    "analyze",
    "simplify",
    "load",
    "save",
    "set_memory_limit",
    "memory_limit",
    "Topology",
    "Surface",
    "Handle",
    "Loop",
    "Report",
    "Volume",
]

#: ``progress(stage, done, total)``; ``None``: a tqdm bar when tqdm is installed and the session
#: interactive; ``True``: a tqdm bar in any case; ``False``: nothing.
Progress = Union[Callable[[str, int, int], Any], None, bool]
Spacing = Optional[Sequence[float]]

# The sample types the native code stores; others are converted when that loses nothing.
_STORED = {np.dtype(t) for t in ("u1", "i1", "u2", "i2", "u4", "i4", "f4", "f8")}


# --------------------------------------------------------------------------------------------
# Results


def _bbox(b: Dict[str, Any]) -> Tuple[Tuple[int, int, int], Tuple[int, int, int]]:
    """A report's ``{"min": [x, y, z], "max": [x, y, z]}`` as two tuples."""
    return (tuple(b["min"]), tuple(b["max"]))


@dataclass(frozen=True)
class Surface:
    """One closed surface of the isosurface."""

    id: int
    #: Handles on this surface.
    genus: int
    #: Its Euler characteristic (2 - 2·genus).
    chi: int
    #: "material" for a component's outer boundary, "cavity" for a void's.
    encloses: str
    #: Area in mm² of the triangulated surface (voxel units when no spacing was given).
    area: float
    #: Voxel index bounds ``((xmin, ymin, zmin), (xmax, ymax, zmax))``, inclusive.
    bbox: Tuple[Tuple[int, int, int], Tuple[int, int, int]]

    @classmethod
    def _from(cls, d: Dict[str, Any]) -> "Surface":
        return cls(
            id=d["id"],
            genus=d["genus"],
            chi=d["chi"],
            encloses=d["encloses"],
            area=d["area"],
            bbox=_bbox(d["bbox"]),
        )


@dataclass(frozen=True)
class Topology:
    """What :func:`genus` found: the solid's Betti numbers and each surface."""

    #: Components of the solid.
    b0: int
    #: Handles: the total genus of its surfaces.
    b1: int
    #: Cavities.
    b2: int
    #: Euler characteristic of the solid, b0 - b1 + b2.
    chi: int
    #: Every closed surface, by decreasing genus.
    surfaces: List[Surface] = field(repr=False)
    _json: Dict[str, Any] = field(repr=False, compare=False)

    def __repr__(self) -> str:
        return (f"Topology(b0={self.b0}, b1={self.b1}, b2={self.b2}, chi={self.chi}, "
                f"{len(self.surfaces)} surfaces)")

    @property
    def genus(self) -> int:
        """The total genus (b1)."""
        return self.b1

    def to_dict(self) -> Dict[str, Any]:
        """The command line's ``genus --json`` report (same keys)."""
        return json.loads(json.dumps(self._json))


@dataclass(frozen=True)
class Loop:
    """A closed curve on the isosurface."""

    #: Length in voxel edges along the surface graph (what ``tau`` counts).
    length: int
    #: Length in millimetres along the interpolated surface (voxels when no spacing was given).
    length_mm: float
    #: "material" if the loop goes round material (a cut across it removes the handle),
    #: "void" if round empty space (a fill across it removes the handle).
    encloses: str
    #: The loop's points, ``(n, 3)`` float, in voxel coordinates ``[x, y, z]``.
    points: np.ndarray = field(repr=False, compare=False)

    @classmethod
    def _from(cls, d: Optional[Dict[str, Any]]) -> Optional["Loop"]:
        if d is None:
            return None
        pts = np.asarray(d["points"], dtype=np.float64).reshape(-1, 3)
        return cls(
            length=d["length"], length_mm=d["length_mm"], encloses=d["encloses"], points=pts
        )


@dataclass(frozen=True)
class Handle:
    """One handle, with its two shortest loops (see :func:`analyze`)."""

    id: int
    #: The shorter loop's length in voxel edges; None when both exceed the search limit.
    size: Optional[int]
    #: The same in millimetres.
    size_mm: Optional[float]
    #: How the sweep found it: "reeb_cycle" (a cycle of the Reeb graph) or "intra_ribbon"
    #: (within one ribbon, by a small volume's own sweep).
    kind: str
    #: The surface it is on (an index into ``genus(...).surfaces``).
    surface: int
    #: Voxel bounds of its loops, ``((xmin, ymin, zmin), (xmax, ymax, zmax))``.
    bbox: Tuple[Tuple[int, int, int], Tuple[int, int, int]]
    #: The loop round the handle's tunnel.
    reeb_loop: Optional[Loop]
    #: The loop across the handle, crossing the Reeb loop once.
    cross_loop: Optional[Loop]
    #: Both loops are the shortest of their kind (no search ran out of budget).
    exact: bool
    _json: Dict[str, Any] = field(repr=False, compare=False)

    @classmethod
    def _from(cls, d: Dict[str, Any]) -> "Handle":
        return cls(
            id=d["id"],
            size=d.get("size"),
            size_mm=d.get("size_mm"),
            kind=d["kind"],
            surface=d["surface"],
            bbox=_bbox(d["bbox"]),
            reeb_loop=Loop._from(d.get("reeb_loop")),
            cross_loop=Loop._from(d.get("cross_loop")),
            exact=bool(d.get("exact", True)),
            _json=d,
        )

    def to_dict(self) -> Dict[str, Any]:
        """This handle as in the command line's ``analyze --json`` report."""
        return json.loads(json.dumps(self._json))


@dataclass(frozen=True)
class Report:
    """What :func:`simplify` did."""

    #: Total genus (handles) before and after.
    genus_before: int
    genus_after: int
    #: The closures made, each a dict: the loop closed (size, lengths, operation "collapse" or
    #: "pinch"), the samples changed, its box, and how many handles it removed ("handles").
    removed: List[Dict[str, Any]] = field(repr=False)
    #: The handles kept (size at least tau, or a closure refused), each as a dict.
    kept: List[Dict[str, Any]] = field(repr=False)
    #: Handles the well-composed step opened through a critical face nothing else mended (the
    #: other connectivity saw them there), each closed again by a later pass: the handles of
    #: ``removed`` add up to ``genus_before - genus_after + handles_opened``.
    handles_opened: int
    #: Samples whose side of the isovalue changed (walls and the well-composed step).
    samples_changed: int
    #: The isovalue to give another mesher (skimage.measure.marching_cubes, VTK) for the
    #: surface isotopo simplified (differs from iso only for integer samples at the isovalue).
    mesh_iso: float
    #: Components (b0) and cavities (b2) of the solid before and after.
    components_before: int
    components_after: int
    cavities_before: int
    cavities_after: int
    #: The components and cavities removed: counts per operation ("components_deleted",
    #: "components_bridged", "cavities_filled", "cavities_opened"), the samples they changed,
    #: and each one ("removed": its kind, operation, size, box, bridge or tunnel samples).
    parts: Dict[str, Any] = field(repr=False)
    _json: Dict[str, Any] = field(repr=False, compare=False)

    def __repr__(self) -> str:
        return (f"Report(genus_before={self.genus_before}, genus_after={self.genus_after}, "
                f"components {self.components_before} -> {self.components_after}, "
                f"cavities {self.cavities_before} -> {self.cavities_after}, "
                f"samples_changed={self.samples_changed}, mesh_iso={self.mesh_iso})")

    def to_dict(self) -> Dict[str, Any]:
        """The command line's ``simplify --report`` JSON (same keys)."""
        return json.loads(json.dumps(self._json))

    def __getitem__(self, key: str) -> Any:
        return self._json[key]


@dataclass(frozen=True)
class Volume:
    """A volume read by :func:`load`."""

    #: The samples, indexed ``[x, y, z]`` (Fortran order): the stored type, or values
    #: (float32; float64 for 32-bit samples) when the header scales them.
    array: np.ndarray = field(repr=False)
    #: Voxel index -> world millimetres (RAS+, as nibabel's ``img.affine``), 4×4.
    affine: np.ndarray = field(repr=False)
    #: The file's header, kept for :func:`save` (``like=``).
    header: Any = field(repr=False)

    @property
    def spacing(self) -> Tuple[float, float, float]:
        """Voxel size in millimetres along x, y, z (pass it as ``spacing=``)."""
        return tuple(self.header.spacing)

    @property
    def path(self) -> str:
        return str(self.header.path)


# --------------------------------------------------------------------------------------------
# Arguments


def _check_iso(iso: Any) -> float:
    if isinstance(iso, (bool, np.bool_)) or not isinstance(iso, (int, float, np.number)):
        raise TypeError(f"iso must be a number, not {type(iso).__name__}")
    if isinstance(iso, np.complexfloating):
        raise TypeError("iso must be a real number")
    value = float(iso)
    if not math.isfinite(value):
        raise ValueError("the isovalue must be a finite number")
    return value


def _check_choice(name: str, value: Any, choices: Sequence[Any]) -> Any:
    if value not in choices or isinstance(value, bool):
        shown = ", ".join(repr(c) for c in choices)
        raise ValueError(f"{name} must be one of {shown}, not {value!r}")
    return value


def _check_spacing(spacing: Spacing) -> Optional[List[float]]:
    if spacing is None:
        return None
    if np.isscalar(spacing):
        spacing = [spacing] * 3
    s = [float(x) for x in spacing]
    if len(s) != 3 or not all(math.isfinite(x) and x > 0 for x in s):
        raise ValueError(f"spacing must be three positive voxel sizes in mm, got {spacing!r}")
    return s


class _Prepared:
    """A volume as the native code reads it, and how to give results back in its type."""

    def __init__(self, volume: Any, iso: float, writable: bool):
        #: A loaded file's geometry (its affine's three top rows), for lengths and boxes in mm.
        self.affine: Optional[List[List[float]]] = None
        #: A loaded file's name: the HTML report's title.
        self.title: Optional[str] = None
        if isinstance(volume, Volume):
            self.affine = volume.affine[:3].tolist()
            self.title = os.path.basename(volume.path)
            volume = volume.array
        arr = np.asarray(volume)
        if arr.ndim != 3:
            raise ValueError(
                f"expected a 3-D volume indexed [x, y, z], got an array of shape {arr.shape}"
            )
        if 0 in arr.shape:
            raise ValueError(f"the volume is empty: shape {arr.shape}")
        self.dtype = arr.dtype
        self.array = self._stored(arr, iso, writable)

    def _stored(self, arr: np.ndarray, iso: float, writable: bool) -> np.ndarray:
        dt = arr.dtype
        if dt.kind == "b":
            # Inside where True: any iso in [0, 1) with inside above (0.5 is usual).
            return arr.view(np.uint8)
        if dt.kind in "iu" and dt.itemsize == 8:
            # int64 labels (numpy's default integer, skimage.measure.label): narrowed to 32 bits
            # when every sample fits, and widened back on output.
            lo, hi = arr.min(), arr.max()
            for t in (np.int32, np.uint32):
                info = np.iinfo(t)
                if info.min <= lo and hi <= info.max:
                    return arr.astype(t)
            raise TypeError(
                f"{dt} samples beyond the 32-bit range ({lo}..{hi}); isotopo stores 8-, 16- and "
                "32-bit integers and float32/float64: convert the volume (e.g. to float64)"
            )
        if dt.kind in "iuf" and dt.newbyteorder("=") in _STORED and not dt.isnative:
            return arr.astype(dt.newbyteorder("="))
        if dt.kind == "f" and dt.itemsize < 4 and not writable:
            return arr.astype(np.float32)  # float16: read exactly as float32
        if dt in _STORED:
            return arr
        raise TypeError(
            f"unsupported sample type {dt}; isotopo reads bool, uint8, int8, uint16, int16, "
            "uint32, int32, int64 (within 32 bits), float32 and float64"
        )

    def restore(self, out: np.ndarray) -> np.ndarray:
        """`out` (in the stored type) in the input's type."""
        if out.dtype == self.dtype:
            return out
        if self.dtype.kind == "b":
            return out != 0
        return out.astype(self.dtype)


def _surface_opts(iso: float, inside: str, connectivity: int) -> Dict[str, Any]:
    return {
        "iso": iso,
        "inside": _check_choice("inside", inside, ("above", "below")),
        "connectivity": _check_choice("connectivity", connectivity, (6, 26)),
    }


def _check_bool_iso(prep: _Prepared, iso: float, inside: str) -> None:
    if prep.dtype.kind == "b" and not 0.0 <= iso < 1.0:
        raise ValueError(
            f"a bool volume's isosurface lies between False (0) and True (1): use an iso in "
            f"[0, 1), such as 0.5 (got {iso})"
        )


# --------------------------------------------------------------------------------------------
# Progress


class _Bar:
    """A tqdm bar per stage."""

    def __init__(self, tqdm: Any):
        self._tqdm = tqdm
        self._bar: Any = None
        self._stage: Optional[str] = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage != self._stage:
            self.close()
            self._stage = stage
            self._bar = self._tqdm(total=total or None, desc=stage, leave=False, unit="")
        if self._bar is not None:
            self._bar.n = done
            self._bar.refresh()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def _interactive() -> bool:
    try:
        return sys.stderr.isatty() or "ipykernel" in sys.modules
    except (AttributeError, ValueError):
        return False


def _progress(progress: Progress) -> Tuple[Optional[Callable[..., Any]], Optional[_Bar]]:
    if progress is False:
        return None, None
    if progress is None or progress is True:
        if progress is None and not _interactive():
            return None, None
        try:
            from tqdm.auto import tqdm
        except ImportError:
            return None, None
        bar = _Bar(tqdm)
        return bar, bar
    if not callable(progress):
        raise TypeError("progress must be a callable progress(stage, done, total), None or False")
    return progress, None


def _run(job: Callable[[Optional[Callable[..., Any]]], Any], progress: Progress) -> Any:
    callback, bar = _progress(progress)
    try:
        return job(callback)
    finally:
        if bar is not None:
            bar.close()


# --------------------------------------------------------------------------------------------
# Jobs


def genus(
    volume: Any,
    iso: float,
    *,
    inside: str = "above",
    connectivity: int = 6,
    spacing: Spacing = None,
    progress: Progress = None,
) -> Topology:
    """Components (b0), handles (b1, the total genus) and cavities (b2) of the solid
    ``volume > iso`` (or ``< iso`` with ``inside="below"``), and every surface of it.

    One streaming pass; ``spacing`` (mm) only scales the surfaces' areas.
    """
    iso = _check_iso(iso)
    opts = _surface_opts(iso, inside, connectivity)
    opts["spacing"] = _check_spacing(spacing)
    prep = _Prepared(volume, iso, writable=False)
    _check_bool_iso(prep, iso, inside)
    opts["affine"] = prep.affine if spacing is None else None
    d = json.loads(_run(lambda cb: _native.genus(prep.array, opts, cb), progress))
    return Topology(
        b0=d["b0"],
        b1=d["b1"],
        b2=d["b2"],
        chi=d["chi"],
        surfaces=[Surface._from(s) for s in d["surfaces"]],
        _json=d,
    )


def analyze(
    volume: Any,
    iso: float,
    *,
    inside: str = "above",
    connectivity: int = 6,
    axis: str = "z",
    spacing: Spacing = None,
    tau: Optional[float] = None,
    lengths: str = "edges",
    max_slices: Optional[int] = None,
    html: Optional[Any] = None,
    progress: Progress = None,
) -> List[Handle]:
    """Every handle of the isosurface, each with its Reeb loop (round its tunnel) and cross
    loop (across it), the shortest on the whole surface; ``size`` is the shorter one's length.

    ``lengths``: loops shortest in voxel "edges" (what simplify's tau counts), in "mm" along
    the interpolated surface (with ``spacing``), or "both". ``tau`` (edges, faster): loops are
    measured exactly below it; a handle with none below it gets some longer Reeb loop (its
    ``size`` is then at least tau, not necessarily its shortest) and no cross loop.
    ``axis``: the sweep's direction.
    ``max_slices``: planes held in memory at once (the rest in a scratch file).
    ``html``: also write the HTML report there (the command line's ``analyze --html``: plots
    with a tau slider, the handles in a table and in 3D; one file, opens offline).
    """
    iso = _check_iso(iso)
    opts = _surface_opts(iso, inside, connectivity)
    opts.update(
        html=None if html is None else _fspath(html),
        axis=_check_choice("axis", axis, ("x", "y", "z")),
        spacing=_check_spacing(spacing),
        lengths=_check_choice("lengths", lengths, ("edges", "mm", "both")),
        tau=_check_tau(tau, allow_zero=False) if tau is not None else None,
        max_slices=_check_max_slices(max_slices),
    )
    if opts["tau"] is not None and math.isinf(opts["tau"]):
        opts["tau"] = None
    prep = _Prepared(volume, iso, writable=False)
    _check_bool_iso(prep, iso, inside)
    opts["affine"] = prep.affine if spacing is None else None
    opts["title"] = prep.title
    d = json.loads(_run(lambda cb: _native.analyze(prep.array, opts, cb), progress))
    return [Handle._from(h) for h in d["handles"]]


def _check_max_slices(max_slices: Any) -> Optional[int]:
    if max_slices is None:
        return None
    if isinstance(max_slices, bool) or not isinstance(max_slices, (int, np.integer)):
        raise TypeError(f"max_slices must be an integer, not {max_slices!r}")
    if max_slices < 0:
        raise ValueError(f"max_slices must be 0 (the whole volume) or more, got {max_slices}")
    return int(max_slices)


def _check_tau(tau: Any, allow_zero: bool) -> float:
    if isinstance(tau, (bool, np.bool_)) or not isinstance(tau, (int, float, np.number)):
        raise TypeError(f"tau must be a number (math.inf removes every handle), not {tau!r}")
    value = float(tau)
    if math.isnan(value) or value < 0 or (value == 0 and not allow_zero):
        what = "0 or more" if allow_zero else "positive"
        raise ValueError(f"tau must be {what} (or math.inf), got {tau!r}")
    return value


def simplify(
    volume: Any,
    iso: float,
    tau: Optional[float] = None,
    *,
    min_component: Optional[int] = None,
    largest: bool = False,
    min_cavity: Optional[int] = None,
    fill_cavities: bool = False,
    spherical: bool = False,
    keep_handles: Optional[int] = None,
    inside: str = "above",
    connectivity: int = 6,
    fill_only: bool = False,
    cut_only: bool = False,
    max_ratio: Optional[float] = None,
    axis: str = "z",
    spacing: Spacing = None,
    metric: str = "edges",
    well_composed: bool = True,
    max_slices: Optional[int] = None,
    html: Optional[Any] = None,
    progress: Progress = None,
) -> Tuple[np.ndarray, Report]:
    """Removes every handle smaller than ``tau`` and returns ``(array, report)``: a new array
    of the input's type and shape (the input is never modified) and what was done.

    - ``tau``: size in voxel edges (``metric="mm"``: millimetres along the surface, with
      ``spacing``) below which a handle is removed; ``math.inf`` removes every handle, 0 none.
    - ``fill_only`` / ``cut_only``: only add material (close tunnels) / only remove it (cut
      handles); by default whichever changes fewer samples.
    - ``max_ratio``: keep long skinny handles, whose longer loop is more than this many times
      the shorter.
    - ``well_composed``: also flip a few samples (changing no topology) so that every mesher
      (skimage.measure.marching_cubes, VTK, either connectivity) sees the same surface; give
      them ``report.mesh_iso``.
    - ``max_slices``: planes held in memory at once (the rest in a scratch file).
    - ``min_component``: components with fewer inside samples go, each deleted or bridged to
      a component that stays, whichever changes fewer samples; ``largest``: keep only the
      largest component.
    - ``min_cavity``: cavities with fewer samples go, each filled or opened to the outside
      through its thinnest wall, whichever changes fewer samples; ``fill_cavities``: every one.
    - ``spherical``: one component, no cavity, no handle (``largest``, ``fill_cavities``,
      ``tau=math.inf``); ``tau`` may then be left out.
    - ``keep_handles``: remove handles from the smallest up until this many are left, whatever
      their size (instead of ``tau``).
    - ``html``: also write the HTML report there (``simplify --html``: the handles removed and
      kept, each in 3D before and after with its wall).

    Components and cavities change only as asked; the result is checked before it is returned.
    """
    if spherical:
        if tau is not None and tau != math.inf:
            raise ValueError(f"spherical removes every handle: leave tau out (got {tau!r})")
        tau, largest, fill_cavities = math.inf, True, True
    if keep_handles is not None:
        if tau is not None or spherical:
            raise ValueError("keep_handles replaces tau: give one of tau, keep_handles, spherical")
        if isinstance(keep_handles, bool) or not isinstance(keep_handles, (int, np.integer)) \
                or keep_handles < 0:
            raise ValueError(f"keep_handles must be a whole number, 0 or more, got {keep_handles!r}")
        tau = math.inf
    if tau is None:
        raise ValueError("give tau (math.inf removes every handle), or spherical=True")
    iso = _check_iso(iso)
    opts = _surface_opts(iso, inside, connectivity)
    if max_ratio is not None:
        max_ratio = float(max_ratio)
        if not max_ratio >= 1:
            raise ValueError(f"the maximum ratio must be at least 1, got {max_ratio}")
    opts.update(
        tau=_check_tau(tau, allow_zero=True),
        fill_only=bool(fill_only),
        cut_only=bool(cut_only),
        max_ratio=max_ratio,
        axis=_check_choice("axis", axis, ("x", "y", "z")),
        spacing=_check_spacing(spacing),
        metric=_check_choice("metric", metric, ("edges", "mm")),
        well_composed=bool(well_composed),
        max_slices=_check_max_slices(max_slices),
        min_component=_check_count("min_component", min_component),
        largest=bool(largest),
        min_cavity=_check_count("min_cavity", min_cavity),
        fill_cavities=bool(fill_cavities),
        keep_handles=None if keep_handles is None else int(keep_handles),
        html=None if html is None else _fspath(html),
    )
    if fill_only and cut_only:
        raise ValueError("fill_only and cut_only exclude each other: one, or neither (both)")
    prep = _Prepared(volume, iso, writable=True)
    _check_bool_iso(prep, iso, inside)
    opts["affine"] = prep.affine if spacing is None else None
    opts["title"] = prep.title
    out = np.array(prep.array, copy=True, order="K")
    d = json.loads(_run(lambda cb: _native.simplify(prep.array, out, opts, cb), progress))
    report = Report(
        genus_before=d["genus_before"],
        genus_after=d["genus_after"],
        removed=d["removed"],
        kept=d["kept"],
        handles_opened=d["handles_opened"],
        samples_changed=d["samples_changed"],
        mesh_iso=d["mesh_iso"],
        components_before=d["b0_before"],
        components_after=d["b0_after"],
        cavities_before=d["b2_before"],
        cavities_after=d["b2_after"],
        parts=d["parts"],
        _json=d,
    )
    return prep.restore(out), report


def _check_count(name: str, value: Optional[int]) -> Optional[int]:
    """A sample count: None, or an integer at least 1."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a whole number of samples, at least 1, got {value!r}")
    return int(value)


# --------------------------------------------------------------------------------------------
# Files


def load(
    path: Union[str, "os.PathLike[str]"],
    *,
    dims: Optional[Sequence[int]] = None,
    dtype: Optional[Any] = None,
    endian: Optional[str] = None,
    offset: int = 0,
    spacing: Spacing = None,
) -> Volume:
    """Reads a volume file (NIfTI, NRRD, MGH/MGZ, MetaImage, NumPy .npy, TIFF, raw): its samples
    indexed ``[x, y, z]``, its affine (RAS+) and its header for :func:`save`.

    A headerless raw file (x fastest) needs ``dims`` (nx, ny, nz) and ``dtype``; ``endian``
    ("little", the default, or "big") and ``offset`` (bytes to skip) may follow. ``spacing``
    (mm) gives the voxel size of the formats that carry none (raw, .npy, TIFF).
    """
    raw = {
        "dims": None if dims is None else [int(n) for n in dims],
        "dtype": None if dtype is None else np.dtype(dtype).name,
        "endian": endian,
        "offset": int(offset),
        "spacing": _check_spacing(spacing),
    }
    try:
        array, header = _native.load(_fspath(path), raw)
    except ValueError as e:
        if "--raw-dims" not in str(e):
            raise
        raise ValueError(
            f"{path}: a headerless raw file needs dims=(nx, ny, nz) and dtype= (x fastest)"
        ) from None
    return Volume(array=array, affine=np.asarray(header.affine, dtype=np.float64), header=header)


def save(
    path: Union[str, "os.PathLike[str]"],
    array: Any,
    like: Optional[Volume] = None,
    *,
    affine: Optional[Any] = None,
) -> None:
    """Writes ``array`` (indexed ``[x, y, z]``) to ``path``, the format from its extension,
    atomically (the file appears whole or not at all).

    ``like``: a :func:`load` result whose header is kept (byte for byte when the array has its
    grid and type, else its geometry); the file it was read from is never overwritten.
    ``affine``: voxel -> world mm, 4×4 (else ``like``'s, else unit voxels at the origin).
    """
    if like is not None and not isinstance(like, Volume):
        raise TypeError("like must be a volume returned by isotopo.load")
    prep = _Prepared(array, 0.5, writable=True)
    a = None
    if affine is not None:
        a = np.asarray(affine, dtype=np.float64)
        if a.shape != (4, 4):
            raise ValueError(f"affine must be 4×4, got shape {a.shape}")
        a = a.tolist()
    _native.save(_fspath(path), prep.array, None if like is None else like.header, a)


def set_memory_limit(limit: Union[int, str, None] = None) -> None:
    """Sets how large this process may grow during isotopo's calls: bytes, a size such as
    ``"2G"`` or ``"512M"`` (powers of 1024), a share of the machine's memory such as ``"50%"``,
    or ``None`` for the default (3/4 of the machine's memory, or of the container's limit).

    The limit counts the whole process, your arrays included: it is what the system's
    out-of-memory killer looks at. A call that would pass it raises ``MemoryError`` saying what
    did not fit (before allocating it, where its size is known in advance), and returns nothing.
    """
    if isinstance(limit, bool) or not (limit is None or isinstance(limit, (int, str))):
        raise TypeError(f"the memory limit must be an int, a str or None, not {type(limit).__name__}")
    _native.set_memory_limit(limit)


def memory_limit() -> int:
    """The memory limit in force, in bytes (see :func:`set_memory_limit`)."""
    return int(_native.memory_limit())


def _fspath(path: Any) -> str:
    import os

    try:
        return os.fspath(path)
    except TypeError:
        raise TypeError(f"expected a file path, not {type(path).__name__}") from None
