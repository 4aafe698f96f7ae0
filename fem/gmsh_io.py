"""A user's volume mesh with named physical groups, read into scikit-fem.

Gmsh 4.1 ``.msh`` files (and any volume format meshio reads that carries named cell
sets) are read through :func:`meshio.read`. The mesh's *physical groups* are what a
scenario refers to by name: volume groups carry materials, surface groups carry heat
sources, convection and clamped supports, point groups name the points of a 3-2-1
support.

Supported cells (one kind per mesh):

* ``tetra`` (4 nodes): :class:`skfem.MeshTet1`, straight-sided; P1 or P2 elements;
* ``tetra10`` (10 nodes, Gmsh ``Mesh.ElementOrder = 2``): :class:`skfem.MeshTet2`,
  curved (isoparametric) geometry, so a circle is represented to O(h³) instead of
  the O(h²) of a polygon; P1 or P2 elements;
* ``hexahedron`` (8 nodes): :class:`skfem.MeshHex1`; Q1 or 20-node serendipity elements.

Coordinates are converted to metres from the declared ``unit`` ("m" or "mm") and the
bounding box is checked for the other unit's tell-tale size. Every refusal is one
:class:`arfem.params.InputError` naming the file (and the group or key).
"""
from __future__ import annotations

import contextlib
import io
import logging
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from skfem import MeshHex1, MeshTet1, MeshTet2

from arfem.params import InputError

__all__ = ["GroupedMesh", "read_grouped_mesh", "grouped_mesh_from_meshio", "UNITS",
           "VOLUME_CELLS", "estimate_memory_bytes", "available_memory_bytes",
           "check_memory", "BBOX_MAX_M", "BBOX_MIN_M", "ELASTIC_DIRECT_MAX_DOFS",
           "ELASTIC_FACTOR_MAX_DOFS", "VTK_TO_SKFEM_HEX"]

#: Declared length units and their factor to metres.
UNITS = {"m": 1.0, "mm": 1e-3}
#: The volume cell kinds arfem solves on (meshio names).
VOLUME_CELLS = ("tetra", "tetra10", "hexahedron")
_OTHER_VOLUME = {"tetra4", "tetra20", "hexahedron20", "hexahedron24", "hexahedron27",
                 "wedge", "wedge12", "wedge15", "wedge18", "pyramid", "pyramid13",
                 "pyramid14", "polyhedron"}
_SURFACE_CELLS = {"triangle": 3, "triangle6": 3, "quad": 4, "quad8": 4, "quad9": 4}
#: A machine-tool structure in metres is smaller than this diagonal [m] ...
BBOX_MAX_M = 20.0
#: ... and larger than this one [m]; outside, the unit is almost certainly wrong.
BBOX_MIN_M = 1e-3


@dataclass(frozen=True)
class GroupedMesh:
    """A volume mesh in metres with its named physical groups.

    Attributes
    ----------
    mesh : skfem.Mesh
        :class:`~skfem.MeshTet1`, :class:`~skfem.MeshTet2` or :class:`~skfem.MeshHex1`;
        coordinates [m].
    cell_type : str
        The file's volume cells: ``"tetra"``, ``"tetra10"`` or ``"hexahedron"``.
    volumes : dict
        Volume group name -> element indices (int arrays) into ``mesh.t``.
    surfaces : dict
        Surface group name -> facet indices into ``mesh.facets``.
    points : dict
        Point group name -> coordinates, shape (3,) [m].
    source : str
        The file read (for messages).
    """

    mesh: object
    cell_type: str
    volumes: dict
    surfaces: dict
    points: dict = field(default_factory=dict)
    source: str = "<mesh>"

    @property
    def group_names(self) -> list[str]:
        """All physical group names, sorted."""
        return sorted({*self.volumes, *self.surfaces, *self.points})

    def describe_groups(self) -> str:
        """One line listing the groups by kind, for error messages."""
        parts = []
        for kind, d in (("volumes", self.volumes), ("surfaces", self.surfaces),
                        ("points", self.points)):
            if d:
                parts.append(f"{kind}: {', '.join(sorted(d))}")
        return "; ".join(parts) if parts else "none"

    def volume_group(self, name: str, where: str) -> np.ndarray:
        """Elements of volume group ``name``; refuses a name the mesh lacks."""
        if name not in self.volumes:
            raise InputError(f"the mesh has no volume group {name!r} (it has "
                             f"{self.describe_groups()})", where)
        return self.volumes[name]

    def surface_group(self, name: str, where: str) -> np.ndarray:
        """Facets of surface group ``name``; refuses a name the mesh lacks."""
        if name not in self.surfaces:
            raise InputError(f"the mesh has no surface group {name!r} (it has "
                             f"{self.describe_groups()})", where)
        return self.surfaces[name]


def read_grouped_mesh(path, unit: str, where: str | None = None) -> GroupedMesh:
    """Read a volume mesh with physical groups into a :class:`GroupedMesh` [m].

    Parameters
    ----------
    path : str or Path
        A Gmsh 4.1 ``.msh`` (or any volume format meshio reads, with named cell sets).
    unit : {"m", "mm"}
        The unit of the file's coordinates.
    where : str, optional
        How to name the file in messages (default: ``path``).

    Returns
    -------
    GroupedMesh

    Raises
    ------
    InputError
        Unreadable file, no physical groups, unsupported or mixed cells, inverted or
        zero-volume elements, a bounding box outside [1 mm, 20 m] after conversion.
    """
    where = str(path) if where is None else where
    if unit not in UNITS:
        raise InputError(f"must be one of {', '.join(UNITS)}, got {unit!r}", "geometry.unit")
    p = Path(path)
    if not p.is_file():
        raise InputError("no such mesh file", where)
    import meshio
    log = logging.getLogger("meshio")
    level = log.level
    log.setLevel(logging.ERROR)
    chatter = io.StringIO()      # meshio's Gmsh reader prints a bare newline to stdout,
    # and where it cannot read a file, the reason (stdout) and an error (stderr)
    try:
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
            m = meshio.read(str(p))
    except (Exception, SystemExit) as exc:   # meshio raises many kinds (ReadError,
        # KeyError, ...) and on a file none of its readers takes calls sys.exit(1)
        text = str(exc) if not isinstance(exc, SystemExit) else chatter.getvalue()
        lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
        msg = lines[0].removeprefix("Error: ") if lines else type(exc).__name__
        raise InputError(f"cannot be read as a mesh ({msg})", where) from None
    finally:
        log.setLevel(level)
    return grouped_mesh_from_meshio(m, unit, where)


def _named_sets(m, where: str):
    """{name: (dim, [bool mask per cell block])} from Gmsh physical tags or cell_sets."""
    sets = {}
    phys = m.cell_data.get("gmsh:physical")
    if m.field_data and phys is not None:
        for name, (tag, dim) in ((k, (int(v[0]), int(v[1]))) for k, v in m.field_data.items()):
            masks = [np.asarray(ph) == tag for ph in phys]
            # the tag must belong to cells of the group's dimension
            masks = [mk & (_cell_dim(cb.type) == dim) for mk, cb in zip(masks, m.cells)]
            sets[name] = (dim, masks)
        return sets
    for name, blocks in (m.cell_sets or {}).items():
        if name.startswith("gmsh:"):
            continue
        masks, dims = [], set()
        for cb, idx in zip(m.cells, blocks):
            mk = np.zeros(len(cb.data), bool)
            if idx is not None and len(idx):
                mk[np.asarray(idx, int)] = True
                dims.add(_cell_dim(cb.type))
            masks.append(mk)
        if dims:
            sets[name] = (max(dims), masks)
    return sets


def _cell_dim(t: str) -> int:
    if t == "vertex":
        return 0
    if t.startswith("line"):
        return 1
    if t in _SURFACE_CELLS or t.startswith(("triangle", "quad", "polygon")):
        return 2
    return 3


def grouped_mesh_from_meshio(m, unit: str, where: str = "<mesh>") -> GroupedMesh:
    """A :class:`GroupedMesh` from a :class:`meshio.Mesh` (see :func:`read_grouped_mesh`)."""
    if unit not in UNITS:
        raise InputError(f"must be one of {', '.join(UNITS)}, got {unit!r}", "geometry.unit")
    sets = _named_sets(m, where)
    if not sets:
        raise InputError("has no physical groups: name the volumes, the heated and "
                         "cooled surfaces and the supports (Gmsh: Physical Volume / "
                         "Physical Surface with a name)", where)
    ctype = _volume_cell_type(m, where)
    pts = np.asarray(m.points, float)
    if pts.shape[1] != 3:
        raise InputError(f"has {pts.shape[1]}-D points; a volume mesh needs 3-D", where)
    pts = pts * UNITS[unit]
    blocks = [i for i, cb in enumerate(m.cells) if cb.type == ctype]
    cells = np.concatenate([np.asarray(m.cells[i].data, np.int64) for i in blocks])
    ncorner = 8 if ctype == "hexahedron" else 4
    corners = cells[:, :ncorner]
    used = np.unique(corners)
    if used.size and (used[0] < 0 or used[-1] >= pts.shape[0]):
        raise InputError(f"a cell names node {int(used[-1] if used[-1] >= pts.shape[0] else used[0])}"
                         f", which the file does not have ({pts.shape[0]} nodes)", where)
    _check_nodes(pts[used], used, unit, where)
    _check_extent(pts[used], unit, where)
    renum = -np.ones(pts.shape[0], np.int64)
    renum[used] = np.arange(used.size)
    t = renum[corners].T.copy()
    p = pts[used].T.copy()
    _check_orientation(p, t, ctype, where)
    if ctype == "hexahedron":
        # meshio/VTK hexahedron node order is skfem's MeshHex1 order up to a permutation
        mesh = MeshHex1(p, t[VTK_TO_SKFEM_HEX])
    else:
        mesh = MeshTet1(p, t)
        if ctype == "tetra10":
            mesh = _quadratic_tet(mesh, pts, cells, renum, used)
    volumes, surfaces, points = _groups(m, sets, blocks, mesh, renum, pts, where)
    for name, el in volumes.items():
        if el.size == 0:
            raise InputError(f"volume group {name!r} has no {ctype} cells", where)
    if not volumes:
        raise InputError("has no physical volume group: every volume must belong to one, "
                         "so that it gets a material", where)
    return GroupedMesh(mesh=mesh, cell_type=ctype, volumes=volumes, surfaces=surfaces,
                       points=points, source=where)


def _volume_cell_type(m, where: str) -> str:
    """The mesh's one kind of volume cell; refuses none, several or an unsupported one."""
    vol_types = {cb.type for cb in m.cells if _cell_dim(cb.type) == 3}
    bad = sorted(vol_types - set(VOLUME_CELLS))
    if bad:
        raise InputError(f"has {', '.join(bad)} cells; arfem solves on one of "
                         f"{', '.join(VOLUME_CELLS)} (Gmsh: Mesh.ElementOrder 1 or 2, no "
                         "serendipity or prism cells)", where)
    if not vol_types:
        raise InputError("has no volume cells (a surface mesh? Gmsh: mesh in 3D)", where)
    if len(vol_types) > 1:
        raise InputError(f"mixes {' and '.join(sorted(vol_types))} cells; arfem needs one "
                         "kind of volume cell per mesh", where)
    return vol_types.pop()


def _check_nodes(pts_m: np.ndarray, ids: np.ndarray, unit: str, where: str) -> None:
    """Every node the cells use at a finite place a machine's part can have
    (:data:`arfem.ranges.RANGES` ``coordinate_m``), before any arithmetic on them: one
    line naming the first node that is not."""
    from arfem.ranges import RANGES
    lo, hi, _ = RANGES["coordinate_m"]
    bad = ~np.all(np.isfinite(pts_m) & (pts_m >= lo) & (pts_m <= hi), axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        x = pts_m[k] / UNITS[unit]
        raise InputError(f"node {int(ids[k])} at ({', '.join(f'{v:g}' for v in x)}) {unit} is "
                         f"not a point of a machine part (every coordinate must be finite and "
                         f"within [{lo / UNITS[unit]:g}, {hi / UNITS[unit]:g}] {unit})", where)


def _check_extent(pts_m: np.ndarray, unit: str, where: str) -> None:
    """Refuse a bounding box (of the cells' corners [m]) larger than a machine or
    smaller than a millimetre: the file's unit is then likely the other one."""
    diag = float(np.linalg.norm(pts_m.max(axis=0) - pts_m.min(axis=0)))
    if diag > BBOX_MAX_M:
        raise InputError(f"bounding box {diag:.3g} m across in unit {unit!r}: larger than a "
                         f"machine ({BBOX_MAX_M:g} m); the file is likely in mm, declare "
                         "geometry.unit = \"mm\"", where)
    if diag < BBOX_MIN_M:
        raise InputError(f"bounding box {diag:.3g} m across in unit {unit!r}: smaller than "
                         f"{BBOX_MIN_M * 1e3:g} mm; the file is likely in m, declare "
                         "geometry.unit = \"m\"", where)


def _groups(m, sets: dict, blocks: list, mesh, renum, pts, where: str):
    """({volume group: element indices}, {surface group: facet indices}, {point group:
    coordinates [m]}) of the named sets on the skfem ``mesh``."""
    offsets, n = {}, 0                 # element index offsets per block, for volume groups
    for i in blocks:
        offsets[i] = n
        n += len(m.cells[i].data)
    volumes, surfaces, points = {}, {}, {}
    facet_index = _FacetIndex(mesh)
    for name, (dim, masks) in sets.items():
        if dim == 3:
            idx = [offsets[i] + np.flatnonzero(masks[i]) for i in blocks]
            volumes[name] = np.concatenate(idx) if idx else np.zeros(0, int)
        elif dim == 2:
            faces = []
            for cb, mk in zip(m.cells, masks):
                if cb.type in _SURFACE_CELLS and mk.any():
                    nc = _SURFACE_CELLS[cb.type]
                    faces.append(renum[np.asarray(cb.data, np.int64)[mk, :nc]])
            if not faces:
                continue
            f = np.concatenate(faces)
            if np.any(f < 0):
                raise InputError(f"surface group {name!r} has nodes no volume cell uses "
                                 "(a surface not on the volume mesh)", where)
            fac = facet_index.find(f)
            if np.any(fac < 0):
                raise InputError(f"surface group {name!r}: {int(np.sum(fac < 0))} faces are "
                                 "not faces of the volume cells (non-conforming surface mesh)",
                                 where)
            surfaces[name] = np.unique(fac)
        elif dim == 0:
            for cb, mk in zip(m.cells, masks):
                if cb.type == "vertex" and mk.any():
                    points[name] = pts[np.asarray(cb.data, np.int64)[mk][0, 0]].copy()
    return volumes, surfaces, points


#: VTK hexahedron corner i -> skfem MeshHex1 corner (skfem's order is x-fastest binary,
#: checked by test_geometry_mesh against skfem's own reference cube).
VTK_TO_SKFEM_HEX = np.array([0, 4, 3, 1, 7, 5, 2, 6])


class _FacetIndex:
    """Find skfem facet indices from corner-node lists (any orientation)."""

    def __init__(self, mesh):
        f = np.sort(mesh.facets, axis=0).T
        self._keys = _row_keys(f)
        self._order = np.argsort(self._keys)

    def find(self, corners: np.ndarray) -> np.ndarray:
        k = _row_keys(np.sort(corners, axis=1))
        pos = np.searchsorted(self._keys[self._order], k)
        pos = np.clip(pos, 0, self._keys.size - 1)
        hit = self._keys[self._order][pos] == k
        out = np.where(hit, self._order[pos], -1)
        return out


def _row_keys(rows: np.ndarray) -> np.ndarray:
    """Keys of integer rows (a void view), equal for equal rows, sortable."""
    r = np.ascontiguousarray(rows.astype(np.int64))
    return r.view(np.dtype((np.void, r.dtype.itemsize * r.shape[1]))).ravel()


def _quadratic_tet(mesh: MeshTet1, pts: np.ndarray, cells: np.ndarray, renum, used):
    """The curved MeshTet2 whose edge nodes sit where the file's tetra10 puts them."""
    m2 = MeshTet2.from_mesh(mesh)
    nv = mesh.p.shape[1]
    # tetra10 (VTK/meshio) edge nodes 4..9 lie on corner pairs:
    pairs = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
    a = np.concatenate([renum[cells[:, i]] for i, _ in pairs])
    b = np.concatenate([renum[cells[:, j]] for _, j in pairs])
    mid = np.concatenate([cells[:, 4 + k] for k in range(6)])
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * nv + hi
    e = mesh.edges
    ekey = np.minimum(e[0], e[1]).astype(np.int64) * nv + np.maximum(e[0], e[1])
    order = np.argsort(key)
    pos = np.searchsorted(key[order], ekey)
    doflocs = m2.doflocs.copy()
    doflocs[:, nv:nv + e.shape[1]] = pts[mid[order][pos]].T
    return replace(m2, doflocs=doflocs)


def _check_orientation(p: np.ndarray, t: np.ndarray, ctype: str, where: str) -> None:
    """Refuse inverted (orientation against the majority) and zero-volume elements."""
    if ctype == "hexahedron":
        # VTK hex: corner c with its three edge neighbours
        nb = [(0, 1, 3, 4), (1, 2, 0, 5), (2, 3, 1, 6), (3, 0, 2, 7),
              (4, 7, 5, 0), (5, 4, 6, 1), (6, 5, 7, 2), (7, 6, 4, 3)]
        vols = np.stack([_triple(p, t[c], t[a], t[b], t[d]) for c, a, b, d in nb])
        vol = (vols * np.sign(np.median(vols))).min(axis=0)    # worst corner
    else:
        vol = _triple(p, t[0], t[1], t[2], t[3])
    ref = float(np.median(np.abs(vol))) if vol.size else 0.0
    sgn = np.sign(np.median(vol))
    zero = np.abs(vol) <= 1e-10 * max(ref, 1e-300)
    inverted = (np.sign(vol) != sgn) & ~zero
    if np.any(inverted):
        k = int(np.flatnonzero(inverted)[0])
        raise InputError(f"{int(inverted.sum())} inverted elements (e.g. element {k}: "
                         "negative volume); re-mesh or fix the node order", where)
    if np.any(zero):
        k = int(np.flatnonzero(zero)[0])
        raise InputError(f"{int(zero.sum())} elements with zero volume (e.g. element {k}); "
                         "re-mesh", where)


def _triple(p, c, a, b, d):
    """(p_a − p_c) · ((p_b − p_c) × (p_d − p_c)) per element (6 × the tet's volume)."""
    pc = p[:, c]
    return np.einsum("ij,ij->j", p[:, a] - pc, np.cross(p[:, b] - pc, p[:, d] - pc, axis=0))


# -- memory ---------------------------------------------------------------------------------

#: nnz(L + U) ≈ FILL_COEFF · n^{4/3} for METIS-ordered 3D factors (n the order). Measured
#: 23 on the rod's 20-node-brick heat matrix (9948 unknowns, 4.89 M entries,
#: fem/linsolve.py) and 23.4 on the spindle unit's P2-tetrahedron elastic stiffness
#: (75 255 unknowns, 74.6 M entries); 30 leaves a margin.
FILL_COEFF = 30.0
#: The same for the P2-tetrahedron heat operator (one unknown per node, 26 entries per
#: row): measured 12.5 on the shipped spindle unit (25 271 unknowns, 9.26 M entries) and
#: 15.6 on its 97 393-unknown version (70.1 M entries; 2026-11-25); it grows slowly with
#: n, so 20 leaves a margin up to about 500k unknowns.
HEAT_FILL_COEFF = 20.0
#: Bytes per factor entry at the peak: value and index (12) doubled for SuperLU's
#: working copies; the shipped spindle unit's run peaked at 2.4 GB with its elastic
#: factor of 74.6 M entries.
BYTES_PER_ENTRY = 24.0
#: Up to this many displacement unknowns the elastic stiffness is factored; above, its
#: solves are AMG-preconditioned CG (:mod:`arfem.fem.body`), whose memory grows linearly.
ELASTIC_DIRECT_MAX_DOFS = 50_000
#: Up to this many the stiffness may still be factored for the many solves of field
#: snapshots (:meth:`arfem.fem.body.ElasticBody.displacement`): the estimate counts the
#: factor up to here.
ELASTIC_FACTOR_MAX_DOFS = 150_000
#: Bytes per displacement unknown of the AMG path at its peak: the assembled stiffness
#: (about 81 entries per row for P2 tetrahedra) with its element-matrix triplets during
#: assembly, the free-dof copy and pyamg's hierarchy. Calibrated on the spindle unit
#: (2026-11-25, sensors only, peak ru_maxrss): 50 536 heat unknowns, peak 2.60 GB,
#: estimate 2.70 GB; 97 393, peak 4.17 GB, estimate 5.35 GB; and on the factored path,
#: 25 271 with fields, peak 2.72 GB, estimate 3.26 GB.
AMG_BYTES_PER_DOF = 6_000.0
#: Dense columns per temperature unknown the reduced solve holds at its peak: the Krylov
#: basis (up to :data:`arfem.fem.thermal3d.KRYLOV_CAP` = 400 vectors), its Ritz vectors
#: and A·V, 8 bytes each.
KRYLOV_COLUMNS = 3 * 400
#: The interpreter, NumPy, SciPy, scikit-fem and meshio loaded [bytes].
BASE_BYTES = 300e6


def estimate_memory_bytes(n_heat_dofs: int, nnz_per_row_heat: float = 30.0) -> int:
    """Peak memory [bytes] of a geometry run, estimated before anything is assembled.

    The run holds the heat matrices (M, K, one per convection group and the operators
    built from them), one factor of the conductance (nnz(L+U) ≈ :data:`HEAT_FILL_COEFF`
    · n^{4/3} for a METIS-ordered P2 mesh, :data:`FILL_COEFF` for others,
    :data:`BYTES_PER_ENTRY` each), the reduced
    solve's dense basis (:data:`KRYLOV_COLUMNS` columns), and the elastic stiffness
    (3n unknowns): its factor up to :data:`ELASTIC_FACTOR_MAX_DOFS` unknowns, else the
    AMG hierarchy (:data:`AMG_BYTES_PER_DOF`).

    Parameters
    ----------
    n_heat_dofs : int
        Temperature unknowns n.
    nnz_per_row_heat : float
        Stored entries per row of a heat matrix (P2 tetrahedra about 30, P1 about 14).

    Returns
    -------
    int
        Estimated peak bytes.

    Examples
    --------
    >>> estimate_memory_bytes(100_000) < estimate_memory_bytes(500_000)
    True
    """
    n = float(n_heat_dofs)
    heat_mats = 6 * n * nnz_per_row_heat * 12
    heat_factor = (HEAT_FILL_COEFF if nnz_per_row_heat >= 20 else FILL_COEFF) \
        * n ** (4 / 3) * BYTES_PER_ENTRY
    krylov = KRYLOV_COLUMNS * n * 8
    n_u = 3 * n
    elastic = (FILL_COEFF * n_u ** (4 / 3) * BYTES_PER_ENTRY if n_u <= ELASTIC_FACTOR_MAX_DOFS
               else AMG_BYTES_PER_DOF * n_u)
    return int(heat_mats + heat_factor + krylov + elastic + BASE_BYTES)


def available_memory_bytes() -> int:
    """Memory this process may use [bytes]: MemAvailable of /proc/meminfo, or the
    ``ARFEM_MEMORY_LIMIT_BYTES`` environment variable when set (tests, batch limits)."""
    env = os.environ.get("ARFEM_MEMORY_LIMIT_BYTES")
    if env:
        return int(float(env))
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):   # pragma: no cover - exotic platforms
        return 1 << 62


def check_memory(n_heat_dofs: int, where: str, nnz_per_row_heat: float = 30.0) -> int:
    """Refuse a model whose estimated memory exceeds what the machine has; returns the
    estimate [bytes]."""
    need = estimate_memory_bytes(n_heat_dofs, nnz_per_row_heat)
    have = available_memory_bytes()
    if need > have:
        raise InputError(f"{n_heat_dofs} temperature unknowns need an estimated "
                         f"{need / 1e9:.1f} GB (matrices and factors), more than the "
                         f"{have / 1e9:.1f} GB available; use a coarser mesh or "
                         "geometry.order = 1", where)
    return need
