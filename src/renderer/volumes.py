"""Volume sources baked to one voxel grid, and tabulated phase functions.

Every heterogeneous medium ends up as a dense float32 density array indexed ``[x, y, z]`` plus a
4x4 ``to_world`` that places the unit cube (voxel (i, j, k) centred at ((i, j, k) + 0.5) / res),
whatever its source; our renderer and Mitsuba both receive exactly that grid.

- OpenVDB files (:func:`read_vdb`) through Debian's ``pyopenvdb`` (numpy < 2 required).
- Multi-octave Perlin noise (:func:`perlin_density`): Perlin's improved gradient noise
  (K. Perlin, "Improving noise", SIGGRAPH 2002), summed as fractal Brownian motion.
- A step function (:func:`step_density`), for debugging multiple scattering.
- A Lorenz-Mie phase table for water droplets (:func:`mie_phase_table`): the series of
  Bohren & Huffman, "Absorption and Scattering of Light by Small Particles" (1983), appendix A
  (BHMIE), averaged over the modified gamma size distribution of Hansen & Travis,
  "Light scattering in planetary atmospheres" (1974), eq. 2.56.
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from renderer.errors import PgiError, one_line

# --------------------------------------------------------------------------- OpenVDB


# Voxels per axis of any baked grid (1024^3 float32 is 4 GiB).
MAX_GRID_SIDE = 1024
# OpenVDB addresses voxels by 32-bit coordinates, and reading near the end of that range
# overflows inside OpenVDB (a crash at 2^31 - 4096): boxes keep well inside it.
MAX_VDB_COORD = 2**30


def unit_cube_to_index(lo: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """4x4 map from the unit cube to OpenVDB index space for a dense copy of voxels
    lo .. lo + shape - 1 (OpenVDB voxel centres sit at integer index coordinates)."""
    m = np.eye(4)
    m[:3, :3] = np.diag(np.asarray(shape, np.float64))
    m[:3, 3] = np.asarray(lo, np.float64) - 0.5
    return m


# Memory an OpenVDB read may claim beyond the process's size (and 64x the file's size, if
# more): a truncated file's garbage length fields made OpenVDB claim 15 GB for a minute.
_VDB_READ_MEMORY = 1 << 30


@contextlib.contextmanager
def address_space_budget(extra: int) -> Iterator[None]:
    """Caps the process's address space at its current size plus ``extra`` bytes for the
    duration: an allocation beyond it fails at once (MemoryError) instead of paging the
    machine. For a library parsing a file while nothing else runs; no cap where Linux's
    /proc or the resource module is missing."""
    try:
        import resource

        pages = int(Path("/proc/self/statm").read_text().split()[0])
        cap = pages * os.sysconf("SC_PAGE_SIZE") + extra
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        yield
        return
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    if soft != resource.RLIM_INFINITY and soft <= cap:
        yield
        return
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def read_vdb(
    path: str | Path, grid_name: str = "density", bbox: tuple | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Density ``[x, y, z]`` (float32) of grid ``grid_name`` over its active bounding box (or
    ``bbox`` = ((i0, j0, k0), (i1, j1, k1)), inclusive index bounds) and the 4x4 ``to_world`` of
    the unit cube holding it, from the grid's (linear) index-to-world transform."""
    try:
        import pyopenvdb as vdb
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise PgiError(
            f"{path}: reading .vdb needs pyopenvdb (Debian python3-openvdb, numpy < 2)"
        ) from e
    extra = max(_VDB_READ_MEMORY, 64 * Path(path).stat().st_size)
    try:
        with address_space_budget(extra):
            names = [m["name"] for m in vdb.readAllGridMetadata(str(path))]
            if grid_name not in names:
                raise PgiError(f"{path}: no grid named {grid_name!r} (grids: {', '.join(names)})")
            if names.count(grid_name) > 1:  # OpenVDB would read the first one without a word
                raise PgiError(
                    f"{path}: {names.count(grid_name)} grids are named {grid_name!r}; "
                    "rename them so that the one to render is unique"
                )
            grid = vdb.read(str(path), grid_name)
    except PgiError:
        raise
    except Exception as e:  # MemoryError, or OpenVDB's own (sometimes empty) message
        if isinstance(e, MemoryError):
            why = f"corrupt or truncated (reading it took over {extra / 2**30:.1f} GiB)"
        elif Path(path).stat().st_size == 0:
            why = "the file is empty"
        else:  # OpenVDB's words ("Map is not registered") do not say the file is damaged
            said = one_line(str(e)).strip("'\" ")
            why = f"corrupt or truncated ({said})" if said else "corrupt or truncated"
        raise PgiError(f"{path}: cannot read as an OpenVDB file: {why}") from None
    if grid.valueTypeName != "float":
        raise PgiError(f"{path}: grid {grid_name!r} holds {grid.valueTypeName}, expected float")
    if bbox is None:
        if grid.activeVoxelCount() == 0:
            raise PgiError(f"{path}: grid {grid_name!r} has no active voxels")
        lo, hi = (np.array(c, np.int64) for c in grid.evalActiveVoxelBoundingBox())
    else:
        lo, hi = (np.array(c, np.int64) for c in bbox)
    if np.any(np.abs(np.concatenate([lo, hi])) > MAX_VDB_COORD):  # OpenVDB would crash
        raise PgiError(
            f"{path}: bounding box {lo.tolist()} .. {hi.tolist()} reaches beyond +-2^30 "
            "voxels, where reading it overflows OpenVDB's 32-bit coordinates"
        )
    shape = hi - lo + 1
    if np.any(shape <= 0):
        raise PgiError(f"{path}: empty bounding box {lo.tolist()} .. {hi.tolist()}")
    if np.any(shape > MAX_GRID_SIDE):
        raise PgiError(
            f"{path}: bounding box {lo.tolist()} .. {hi.tolist()} is {shape.tolist()} voxels; "
            f"at most {MAX_GRID_SIDE} per axis"
        )
    dense = np.zeros(tuple(int(s) for s in shape), np.float32)
    grid.copyToArray(dense, ijk=tuple(int(i) for i in lo))
    if not grid.transform.isLinear:
        raise PgiError(f"{path}: grid {grid_name!r} has a non-linear (frustum) transform")
    # The affine index-to-world map, read off the transform at four points.
    t = grid.transform
    origin = np.array(t.indexToWorld((0.0, 0.0, 0.0)))
    index_to_world = np.eye(4)
    for a in range(3):
        e = [0.0, 0.0, 0.0]
        e[a] = 1.0
        index_to_world[:3, a] = np.array(t.indexToWorld(tuple(e))) - origin
    index_to_world[:3, 3] = origin
    return dense, index_to_world @ unit_cube_to_index(lo, shape)


def write_vdb(path: str | Path, density_xyz: np.ndarray, voxel_size: float,
              origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
              grid_name: str = "density", tolerance: float = 0.0) -> None:  # fmt: skip
    """Write a dense ``[x, y, z]`` array as a float grid whose voxel (0, 0, 0) is centred at
    ``origin`` (world), voxels of ``voxel_size``; values <= tolerance become inactive."""
    import pyopenvdb as vdb

    grid = vdb.FloatGrid()
    grid.copyFromArray(np.ascontiguousarray(density_xyz, np.float32), tolerance=tolerance)
    grid.prune(tolerance)
    grid.name = grid_name
    grid.gridClass = vdb.GridClass.FOG_VOLUME
    xform = vdb.createLinearTransform(voxelSize=voxel_size)
    xform.translate(tuple(float(o) for o in origin))
    grid.transform = xform
    vdb.write(str(path), grids=[grid])


# --------------------------------------------------------------------------- procedural


def axis_centres(n: int) -> np.ndarray:
    """Unit-interval coordinates of n voxel centres, (i + 0.5) / n (Mitsuba's convention)."""
    return (np.arange(n) + 0.5) / n


def voxel_centres(resolution: tuple[int, int, int], xs: slice = slice(None)) -> np.ndarray:
    """Unit-cube coordinates of the voxel centres (of the x columns ``xs``), shape (X, Y, Z, 3)."""
    axes = [axis_centres(n) for n in resolution]
    return np.stack(np.meshgrid(axes[0][xs], *axes[1:], indexing="ij"), axis=-1)


# The 12 edge directions of a cube, padded to 16 by repeating four (Perlin 2002).
_GRADIENTS = np.array(
    [[1, 1, 0], [-1, 1, 0], [1, -1, 0], [-1, -1, 0], [1, 0, 1], [-1, 0, 1], [1, 0, -1],
     [-1, 0, -1], [0, 1, 1], [0, -1, 1], [0, 1, -1], [0, -1, -1], [1, 1, 0], [0, -1, 1],
     [-1, 1, 0], [0, -1, -1]], np.float64,
)  # fmt: skip


def _fade(t: np.ndarray) -> np.ndarray:
    return t * t * t * (t * (t * 6 - 15) + 10)


def perlin_noise(points: np.ndarray, seed: int = 0) -> np.ndarray:
    """Improved Perlin gradient noise at (..., 3) points, in about [-1, 1]; lattice period 256.
    The permutation table is drawn from ``seed``."""
    perm = np.random.default_rng(seed).permutation(256)
    perm = np.concatenate([perm, perm]).astype(np.int64)
    p = np.asarray(points, np.float64)
    cell = np.floor(p)
    f = p - cell
    i = cell.astype(np.int64) & 255
    u = _fade(f)
    out = np.zeros(p.shape[:-1])
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                h = perm[perm[perm[i[..., 0] + dx] + i[..., 1] + dy] + i[..., 2] + dz] & 15
                g = _GRADIENTS[h]
                offset = f - np.array([dx, dy, dz], np.float64)
                w = (
                    (u[..., 0] if dx else 1 - u[..., 0])
                    * (u[..., 1] if dy else 1 - u[..., 1])
                    * (u[..., 2] if dz else 1 - u[..., 2])
                )
                out += w * np.sum(g * offset, axis=-1)
    return out


def fbm(points: np.ndarray, octaves: int = 4, frequency: float = 4.0, lacunarity: float = 2.0,
        gain: float = 0.5, seed: int = 0) -> np.ndarray:  # fmt: skip
    """Fractal sum of ``octaves`` Perlin noises: octave k has frequency frequency *
    lacunarity^k and amplitude gain^k (each octave its own permutation)."""
    total = np.zeros(np.shape(points)[:-1])
    for k in range(octaves):
        total += gain**k * perlin_noise(points * (frequency * lacunarity**k), seed + 7919 * k)
    return total


def perlin_density(resolution: tuple[int, int, int], octaves: int = 4, frequency: float = 4.0,
                   lacunarity: float = 2.0, gain: float = 0.5, offset: float = 0.0,
                   seed: int = 0) -> np.ndarray:  # fmt: skip
    """max(0, offset + fbm) at the voxel centres of the unit cube, float32 [x, y, z].

    Baked in slabs of x so that float64 temporaries stay small (a 1024^3 grid at once
    would need tens of GB)."""
    nx, ny, nz = resolution
    out = np.empty((nx, ny, nz), np.float32)
    slab = max(1, _BAKE_POINTS // (ny * nz))
    for x0 in range(0, nx, slab):
        xs = slice(x0, x0 + slab)
        d = offset + fbm(voxel_centres(resolution, xs), octaves, frequency, lacunarity, gain, seed)
        out[xs] = np.maximum(d, 0.0)
    return out


# Voxels baked at once by perlin_density (~0.5 GB of float64 temporaries).
_BAKE_POINTS = 1 << 21


def step_density(resolution: tuple[int, int, int], axis: int = 0, position: float = 0.5,
                 values: tuple[float, float] = (0.0, 1.0)) -> np.ndarray:  # fmt: skip
    """values[0] where the voxel centre's unit-cube coordinate along ``axis`` is below
    ``position``, values[1] from there on; float32 [x, y, z]."""
    # One coordinate per voxel along `axis`, broadcast: no (X, Y, Z, 3) array (tens of GB at
    # the largest grids).
    shape = [1, 1, 1]
    shape[axis] = resolution[axis]
    c = axis_centres(resolution[axis]).reshape(shape)
    step = np.where(c < position, values[0], values[1]).astype(np.float32)
    # A copy: a broadcast view keeps zero strides, which the core refuses.
    return np.broadcast_to(step, tuple(resolution)).copy()


# --------------------------------------------------------------------------- Lorenz-Mie


def mie_amplitudes(x: float, m: complex, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scattering amplitudes S1, S2 of a homogeneous sphere of size parameter x = 2 pi r /
    lambda and relative refractive index m at cos(theta) = mu (Bohren & Huffman, BHMIE)."""
    mu = np.asarray(mu, np.float64)
    nstop = int(x + 4.0 * x ** (1.0 / 3.0) + 2.0)
    y = m * x
    nmx = int(max(nstop, abs(y))) + 15
    # Logarithmic derivative D_n(mx), by downward recurrence (stable).
    d = np.zeros(nmx + 1, complex)
    for n in range(nmx, 0, -1):
        d[n - 1] = n / y - 1.0 / (d[n] + n / y)
    psi0, psi1 = np.cos(x), np.sin(x)
    chi0, chi1 = -np.sin(x), np.cos(x)
    xi1 = complex(psi1, -chi1)
    pi_prev, pi_cur = np.zeros_like(mu), np.ones_like(mu)
    s1 = np.zeros(mu.shape, complex)
    s2 = np.zeros(mu.shape, complex)
    for n in range(1, nstop + 1):
        fn = (2.0 * n + 1.0) / (n * (n + 1.0))
        psi = (2.0 * n - 1.0) * psi1 / x - psi0
        chi = (2.0 * n - 1.0) * chi1 / x - chi0
        xi = complex(psi, -chi)
        da, db = d[n] / m + n / x, m * d[n] + n / x
        an = (da * psi - psi1) / (da * xi - xi1)
        bn = (db * psi - psi1) / (db * xi - xi1)
        tau = n * mu * pi_cur - (n + 1) * pi_prev
        s1 += fn * (an * pi_cur + bn * tau)
        s2 += fn * (an * tau + bn * pi_cur)
        pi_prev, pi_cur = pi_cur, ((2 * n + 1) * mu * pi_cur - (n + 1) * pi_prev) / n
        psi0, psi1, chi0, chi1 = psi1, psi, chi1, chi
        xi1 = complex(psi1, -chi1)
    return s1, s2


def mie_largest_radius(effective_radius: float, effective_variance: float) -> float:
    """The largest droplet radius mie_phase_table integrates over (micrometres)."""
    return effective_radius * (1 + 8 * np.sqrt(effective_variance))


def mie_droplet_radii(effective_radius: float, effective_variance: float,
                      radii: int = 64) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Radii (micrometres) and quadrature weights of the modified gamma distribution of
    Hansen & Travis (1974, eq. 2.56), n(r) ~ r^((1 - 3v) / v) exp(-r / (a v)), whose
    effective radius (the r^2-weighted mean radius) is a and effective variance v."""
    a, v = effective_radius, effective_variance
    r = np.linspace(0.05 * a, mie_largest_radius(a, v), radii)
    weights = r ** ((1 - 3 * v) / v) * np.exp(-r / (a * v)) * np.gradient(r)
    return r, weights


@functools.lru_cache(maxsize=8)
def mie_phase_table(effective_radius: float = 2.0, effective_variance: float = 0.1,
                    wavelength: float = 0.55, ior: float = 1.333,
                    resolution: int = 2048, radii: int = 64) -> np.ndarray:  # fmt: skip
    """Mie phase function of water droplets at cos(theta) = linspace(-1, 1, resolution)
    (Mitsuba ``tabphase`` order: -1 backward .. +1 forward), normalised per steradian.

    Radii follow ``mie_droplet_radii`` (effective radius a, effective variance v); the
    scattered intensity (|S1|^2 + |S2|^2) / 2 is averaged over them (number-weighted; the
    1/k^2 factor is the same for all radii at one wavelength). One wavelength for all RGB
    channels, since ``tabphase`` is not spectral in RGB variants.
    """
    mu = np.linspace(-1.0, 1.0, resolution)
    r, weights = mie_droplet_radii(effective_radius, effective_variance, radii)
    intensity = np.zeros(resolution)
    for ri, wi in zip(r, weights, strict=True):
        s1, s2 = mie_amplitudes(2 * np.pi * ri / wavelength, complex(ior, 0.0), mu)
        intensity += wi * 0.5 * (np.abs(s1) ** 2 + np.abs(s2) ** 2)
    # Normalise the piecewise-linear interpolant, as tabphase does.
    h = 2.0 / (resolution - 1)
    integral = h * (intensity.sum() - 0.5 * (intensity[0] + intensity[-1]))
    table = intensity / (2 * np.pi * integral)
    table.setflags(write=False)
    return table


def tabulated_mean_cosine(values: np.ndarray) -> float:
    """<cos theta> of the piecewise-linear phase function through ``values``."""
    values = np.asarray(values, np.float64)
    mu = np.linspace(-1, 1, len(values))
    fine = np.linspace(-1, 1, 64 * len(values) + 1)
    f = np.interp(fine, mu, values)
    return float(np.trapz(f * fine, fine) / np.trapz(f, fine))
