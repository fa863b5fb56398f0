"""The SO-101 visual meshes of the two render qualities, built from the provider's.

The provider's STL files are CAD exports: 322,564 triangles in all (about 400,000 per
frame once the servo mesh is repeated), most of them far smaller than a pixel. A
software rasteriser spends most of a frame on them, so neither quality draws them as
they are. Each mesh is rebuilt once per machine, with the settings of its quality
(:data:`MESH_SETTINGS`):

1. vertices that share a cell of a grid are merged into one (vertex clustering), which
   removes tessellation finer than the cell;
2. for ``fast`` only, quadric edge-collapse decimation (the ``fast-simplification``
   package) then removes a share of the triangles that remain.

``high`` merges at 0.3 mm, less than a pixel of the wrist camera (the closest view of
the arm) at 640x480: 126,000 triangles are left, frames render about twice as fast and
differ from the provider's meshes by a fraction of a grey level, at edges.
``fast`` merges at 1.5 mm and removes 30 % of what is left: 21,500 triangles, each part
keeps its extent to within about half a millimetre, and frames differ by a few grey
levels (``docs/quality_fast_vs_high.png`` shows both). These settings came from
measuring render time and the difference to the provider's meshes at the front and
wrist cameras. Physics never sees these meshes: the visual geoms have no mass and no
collisions.

The results are cached in the user cache directory (see :mod:`gym_soarm.sim.cache`),
keyed by each source file's SHA-256 and the settings, so the work is done once per
machine.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.metadata
import logging

import numpy as np

from gym_soarm.sim import cache, meshes

logger = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class MeshSettings:
    """How one render quality rebuilds the provider's meshes."""

    weld_cell_m: float  # vertices sharing a cell of this grid become one
    decimation: float  # share of the welded triangles that decimation removes (0: none)


MESH_SETTINGS = {
    "fast": MeshSettings(weld_cell_m=0.0015, decimation=0.3),
    "high": MeshSettings(weld_cell_m=0.0003, decimation=0.0),
}
# Bump when the algorithm changes, so cached meshes of the old one are not reused.
ALGORITHM_VERSION = 3

_STL_HEADER_BYTES = 80
_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])


def stl_triangle_count(data: bytes) -> int:
    """Number of triangles in a binary STL file.

    Raises:
        ValueError: ``data`` is not a binary STL file (or is truncated).
    """
    if len(data) < _STL_HEADER_BYTES + 4:
        raise ValueError(f"expected a binary STL file; got {len(data)} bytes")
    count = int.from_bytes(data[_STL_HEADER_BYTES : _STL_HEADER_BYTES + 4], "little")
    expected = _STL_HEADER_BYTES + 4 + count * _STL_RECORD.itemsize
    if len(data) != expected:
        raise ValueError(
            f"expected a binary STL file of {expected} bytes for {count} triangles; "
            f"got {len(data)} bytes"
        )
    return count


def stl_corners(data: bytes) -> np.ndarray:
    """The (3 m, 3) float32 corners of the m triangles of a binary STL file, in order.

    Raises:
        ValueError: ``data`` is not a binary STL file.
    """
    count = stl_triangle_count(data)
    records = np.frombuffer(data, dtype=_STL_RECORD, count=count, offset=_STL_HEADER_BYTES + 4)
    return records["vertices"].reshape(-1, 3)


def parse_binary_stl(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) float64 and triangles (m, 3) int64 of a binary STL file.

    Identical corner positions become one vertex, so the mesh is indexed.

    Raises:
        ValueError: ``data`` is not a binary STL file.
    """
    corners = stl_corners(data) + np.float32(0.0)  # -0.0 becomes 0.0
    # Rows as 12-byte strings: a 1-D unique is much faster than np.unique(axis=0).
    rows = np.ascontiguousarray(corners).view(np.dtype((np.void, corners.itemsize * 3)))
    _, first, index = np.unique(rows.ravel(), return_index=True, return_inverse=True)
    return corners[first].astype(np.float64), index.reshape(-1, 3).astype(np.int64)


def write_binary_stl(vertices: np.ndarray, triangles: np.ndarray) -> bytes:
    """A binary STL file of the indexed mesh, with unit face normals."""
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(triangles)]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0)
    records = np.zeros(len(corners), dtype=_STL_RECORD)
    records["normal"] = normals
    records["vertices"] = corners
    header = b"gym_soarm simplified visual mesh".ljust(_STL_HEADER_BYTES, b" ")
    return header + len(records).to_bytes(4, "little") + records.tobytes()


def weld_vertices(
    vertices: np.ndarray, triangles: np.ndarray, cell_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Merge the vertices that share a ``cell_m`` grid cell into their mean.

    Triangles that collapse (two corners in one cell) and repeated triangles are
    dropped; unused vertices are removed.
    """
    cells = np.floor(vertices / cell_m).astype(np.int64)
    cells -= cells.min(axis=0)
    extent = cells.max(axis=0) + 1
    keys = (cells[:, 0] * extent[1] + cells[:, 1]) * extent[2] + cells[:, 2]  # one int per cell
    _, cluster = np.unique(keys, return_inverse=True)
    n_clusters = int(cluster.max()) + 1
    merged = np.zeros((n_clusters, 3))
    np.add.at(merged, cluster, vertices)
    merged /= np.bincount(cluster, minlength=n_clusters)[:, None]
    tris = cluster[triangles]
    keep = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
    tris = tris[keep]
    _, first = np.unique(np.sort(tris, axis=1), axis=0, return_index=True)
    tris = tris[np.sort(first)]
    used = np.unique(tris)
    renumber = np.full(n_clusters, -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return merged[used], renumber[tris]


def _mesh_settings(quality: str) -> MeshSettings:
    if quality not in MESH_SETTINGS:
        raise ValueError(f"quality must be one of {tuple(MESH_SETTINGS)}; got {quality!r}.")
    return MESH_SETTINGS[quality]


def simplify_stl(data: bytes, quality: str = "fast") -> bytes:
    """One STL file rebuilt with the settings of ``quality`` (welded, maybe decimated)."""
    settings = _mesh_settings(quality)
    corners = stl_corners(data).astype(np.float64)
    # Welding merges repeated corners along with near ones: no exact de-duplication first.
    triangles = np.arange(len(corners), dtype=np.int64).reshape(-1, 3)
    vertices, triangles = weld_vertices(corners, triangles, settings.weld_cell_m)
    if settings.decimation > 0:
        import fast_simplification

        vertices, triangles = fast_simplification.simplify(
            vertices, triangles.astype(np.int32), target_reduction=settings.decimation
        )
    return write_binary_stl(vertices, triangles)


def settings_tag(quality: str = "fast") -> str:
    """Everything besides the source bytes that the meshes of ``quality`` depend on."""
    settings = _mesh_settings(quality)
    tag = f"v{ALGORITHM_VERSION} {quality} weld={settings.weld_cell_m!r}"
    if settings.decimation > 0:
        try:
            library = importlib.metadata.version("fast-simplification")
        except importlib.metadata.PackageNotFoundError:
            library = "missing"
        tag += f" reduction={settings.decimation!r} fast-simplification={library}"
    return tag


@functools.lru_cache(maxsize=len(MESH_SETTINGS))
def quality_meshes(quality: str = "fast") -> dict[str, bytes]:
    """``{file name: STL bytes}`` of every SO-101 mesh for ``quality`` (cached on disk).

    Raises:
        ValueError: ``quality`` is not one of :data:`MESH_SETTINGS`.
        gym_soarm.sim.meshes.MeshError: a provider mesh is missing or changed.
    """
    tag = settings_tag(quality)
    sources = meshes.load_meshes()  # checks every SHA-256
    result: dict[str, bytes] = {}
    for name in sources:
        key = cache.digest(meshes.MESH_SHA256[name], tag)[:24]
        stem = name.removesuffix(".stl")
        cache_name = f"meshes/{quality}/{stem}-{key}.stl"
        data = cache.read(cache_name)
        if data is not None:
            try:
                if stl_triangle_count(data) == 0:
                    raise ValueError("no triangles")
            except ValueError as exc:
                logger.info("discarding the damaged cached mesh %s (%s)", cache_name, exc)
                data = None
        if data is None:
            data = simplify_stl(sources[name], quality)
            if cache.write(cache_name, data) is not None:
                cache.prune(f"meshes/{quality}/{stem}-*.stl", keep=cache_name)
                cache.prune(f"meshes/{stem}-*.stl", keep="")  # the layout before 0.5
        result[name] = data
    return result
