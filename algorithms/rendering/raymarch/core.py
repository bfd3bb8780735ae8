"""Direct volume rendering by ray marching, with emission-absorption, Blinn-Phong or single-scattering light.

Method
------
For every pixel a ray is cast through the box spanned by the voxel centres (slab test); samples are taken every
``d = sample_distance`` mm, the scalar is reconstructed by trilinear interpolation, mapped through the transfer
function to colour and opacity, and composited front to back (source 002, 2.3.4-2.3.5; source 001, technique 2)::

    C += (1 - A) * a * c,   A += (1 - A) * a,   a = 1 - (1 - alpha) ** (d / unit_distance)

``alpha`` is the transfer function's opacity per ``unit_distance`` mm, so the result does not depend on ``d``:
a homogeneous slab of thickness ``L`` transmits ``(1 - alpha) ** (L / unit_distance) = exp(-sigma * L)`` with
``sigma = -ln(1 - alpha) / unit_distance``. That is source 001's Beer-Lambert product ``I / I0 = (1/2) ** (eps *
integral of density)`` in base e instead of base 2.

Sampling follows VTK's GPU ray caster (measured against ``vtkGPUVolumeRayCastMapper``): without jittering the first
sample lies one sample distance past the box entry, samples continue every ``d`` mm while inside the box of voxel
centres, and the last partial distance is dropped (no sample at the exit, no length weighting). With ``jitter``
(the application's default) each ray's samples move back by ``(1 - j) d``, ``j`` in [0, 1) from the pixel's
interleaved-gradient-noise value (:func:`algorithms.common.sampling.jitter_offset`): rings where a smooth surface
crosses the sample grid at a slant ("wood grain") become fine noise, stable from frame to frame; successive
``pass_index`` values step ``j`` by the golden ratio, so the average of passes converges (accumulation while the
camera rests). A ray from a camera inside the box starts at the camera. Colours and opacities are interpolated in
the (opacity-corrected) table separately and premultiplied per sample, as VTK does.

Lighting models:

``"emission"``
    The transfer function's colour is emitted as is (source 002's emission-absorption model, 2.3.4).
``"phong"``
    Local illumination from gradients (source 002, 2.3.6) in exactly VTK's light model, so shaded frames of ours and
    of ``vtkGPUVolumeRayCastMapper`` agree: ``c' = (ambient + diffuse |n.l|) c + specular max(r.v, 0) ** s`` with
    Phong's reflection vector ``r = 2 (n.l) n - l`` (source 002 writes Blinn's half vector ``h``; with a headlight
    ``n.h = n.l``, a broader highlight than VTK's ``r.v = 2 (n.l)^2 - 1``), a white highlight, two-sided like VTK's
    default renderer, and VTK's headlight: a light at the camera position, ``l = v`` towards the camera from the
    ray's box entry point. The normal is ``n = -grad f / |grad f|`` from central differences one voxel wide of the
    interpolated field (source 002, 2.4.4; VTK's GPU mapper differentiates the same way), i.e. outward where values
    increase inwards, as in CT. In homogeneous regions the gradient has no useful direction: the shaded colour is
    blended with the unshaded one by ``w = min(1, |grad f| / gradient_threshold)`` (value units per mm; 0, the
    default and VTK's behaviour without a gradient-opacity function, shades every sample with a non-zero
    gradient).
``"scatter"``
    Single scattering of a directional light (source 001, technique 2): at each visible sample,
    ``light_samples`` samples towards the light, midpoints of equal parts of the segment up to the box exit, give
    the light that reaches it, ``T = exp(-delta * sum(sigma_j))`` (Beer-Lambert; the segment ends where the path
    leaves the box around the bricks that hold any opacity, since beyond it the extinction is zero, so the light
    samples are spent where they matter; with jitter they move by the pixel's offset too); the sample then scatters
    ``c * scatter_albedo * p(theta) * T`` towards the camera, which the compositing attenuates on the way out
    (source 001's ``I / I0 = sum (I / I_p) * a * (I_p / I0)``). ``p`` is the Henyey-Greenstein phase function with
    asymmetry ``phase``, normalised so isotropic scattering (``phase = 0``) gives 1; there is no ambient term.

Without ``light_direction`` the light is a headlight at the camera, like VTK's default light: ``l = v`` (towards
the camera along each ray). ``light_direction`` gives a directional light instead, as the volume-frame vector
pointing *towards* the light (source 002's ``l``).

Accelerations, neither of which changes the image beyond the stated bound:

- Empty-space skipping: min-max bricks of ``brick_size`` cells per axis are classified once per transfer function;
  a brick is empty when the (corrected) opacity table is zero over the whole range of table entries its values
  can reach. Each empty brick stores its Chebyshev distance ``r`` (in bricks) to the nearest non-empty one. A ray
  first narrows its sample range to the box around all non-empty bricks; on reaching a sample inside an empty
  brick it leaps out of the cube of bricks within distance ``r - 1`` (all empty) to the first sample of its
  regular grid beyond. Skipped samples would have had exactly zero opacity, so the image is bit-identical.
- Early ray termination: a ray stops once its accumulated opacity reaches ``early_termination``; what it would
  still have collected is at most ``(1 - early_termination)`` times the largest colour behind (for emission: the
  largest colour in the table), so each channel changes by at most that much (0.01 at the default 0.99; VTK's
  GPU mapper stops at ``1 - 1/255``).

Performance: the volume is sampled in its own dtype (int16 CT stays int16), the caller's array itself when it is
read-only (the VTK filter passes VTK's memory), else a private copy; the kernels work in index space with the
opacity correction folded into the table (numba, ``parallel=True`` over image rows, interleaved so that every
thread gets rows from all parts of the image). The set-up (conversion, bricks, table correction) happens in the
constructor, so a frame at reduced size for interactive use costs only its rays.

References
----------
Source 001 (Dutch student report comparing three techniques for rendering volumetric data, see docs/references.md),
"Techniek 2: Direct volume rendering" (absorption as a Riemann product, in-scattering; 40 view and 8 light samples
measured). Source 002 (Kähler, *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009),
sections 2.3.1-2.3.6 and 2.4.1-2.4.4 (trilinear reconstruction, transfer function lookup, emission-absorption
integral and compositing, Blinn-Phong from central-difference gradients, gradient-magnitude modulation).

N. Max, "Optical models for direct volume rendering", IEEE TVCG 1(2), 99-108, 1995. DOI 10.1109/2945.468400.
J. F. Blinn, "Models of light reflection for computer synthesized pictures", SIGGRAPH 1977.
DOI 10.1145/563858.563893.
M. Levoy, "Efficient ray tracing of volume data", ACM Transactions on Graphics 9(3), 245-261, 1990.
DOI 10.1145/78964.78965 (early ray termination, space leaping).
L. G. Henyey, J. L. Greenstein, "Diffuse radiation in the galaxy", Astrophysical Journal 93, 70-83, 1941.
DOI 10.1086/144246.

The VTK filter is :class:`algorithms.rendering.raymarch.RaymarchFilter`; the numba kernels are in :mod:`.kernels`.

Examples
--------
>>> renderer = RaymarchRenderer(volume.array, volume.spacing, table, lighting="phong")
>>> frame = renderer.render(camera, 512, 512)          # camera in the volume frame
>>> rgb = frame.to_uint8()                             # (512, 512, 3) over black
"""

from __future__ import annotations

import math
import time

import numba
import numpy as np
from scipy.ndimage import distance_transform_cdt

from ...common.camera import Camera, checked_camera
from ...common.progress import ProgressCallback, report, scaled
from ...common.render_result import RenderResult
from ...common.cutaway import ToolSet, packed_tools
from ...common.transfer import TransferTable, checked_table
from ...common.validation import (
    validated_count,
    validated_distance,
    validated_float_volume,
    validated_image_size,
    validated_shape,
    validated_spacing,
)
from ...common.sampling import sampled_volume
from . import kernels

LIGHTING_MODELS = ("emission", "phong", "scatter")
_LIGHTING_CODES = {"emission": kernels.EMISSION, "phong": kernels.PHONG, "scatter": kernels.SCATTER}
#: Rows rendered between two progress calls (a cancel takes effect within one band).
_ROWS_PER_BAND = 64
#: Opacity per unit distance is capped below 1 for the extinction used by the light march (sigma stays finite).
_MAX_OPACITY = 1.0 - 1e-6


def validated_pass(pass_index) -> int:
    """A jitter pass index: a non-negative integer."""
    if isinstance(pass_index, bool) or not isinstance(pass_index, (int, np.integer)) or pass_index < 0:
        raise ValueError(f"pass_index must be a non-negative integer, got {pass_index!r}")
    return int(pass_index)


def checked_lighting(lighting: str) -> str:
    if lighting not in LIGHTING_MODELS:
        raise ValueError(f"lighting must be one of {', '.join(LIGHTING_MODELS)}, got {lighting!r}")
    return lighting


def _non_negative(name: str, value) -> float:
    value = float(value)
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"{name} must be a finite non-negative number, got {value}")
    return value


def step_for_samples(shape, spacing, samples: int) -> float:
    """The sample distance (mm) that puts ``samples`` samples on the box diagonal: ``diagonal / samples``.

    Source 001 sets the quality by the number of samples per ray (it measured 40 view samples); this converts
    such a count into the ``sample_distance`` of :class:`RaymarchRenderer`. ``shape`` is ``(nz, ny, nx)``,
    ``spacing`` ``(sx, sy, sz)`` mm; the box spans the voxel centres, so its diagonal is
    ``|((nx - 1) sx, (ny - 1) sy, (nz - 1) sz)|``.
    """
    nz, ny, nx = validated_shape(shape, min_size=2)
    sizes = validated_spacing(spacing)
    samples = validated_count(samples, "samples")
    diagonal = float(np.linalg.norm((np.array([nx, ny, nz]) - 1) * sizes))
    return diagonal / samples


def shading_normals(volume_array, points, *, spacing=(1.0, 1.0, 1.0)) -> np.ndarray:
    """The unit normals the ``"phong"`` model shades with, at volume-frame points.

    Parameters
    ----------
    volume_array : ndarray, shape (nz, ny, nx)
        Scalar volume indexed ``[k, j, i]``.
    points : ndarray, shape (n, 3)
        Positions in the volume frame, mm, ``(x, y, z)`` order (voxel ``(i, j, k)`` at ``(i sx, j sy, k sz)``).
    spacing : (sx, sy, sz)
        Voxel size in mm.

    Returns
    -------
    ndarray, shape (n, 3), float64
        ``-grad f / |grad f|`` with the gradient from central differences one voxel wide of the trilinear field
        (zero where the gradient vanishes): outward normals of regions whose values increase inwards.
    """
    volume = validated_float_volume(volume_array)
    sizes = validated_spacing(spacing)
    positions = np.asarray(points, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {positions.shape}")
    gradients = kernels.gradients_at(volume, np.ascontiguousarray(positions / sizes), sizes)
    magnitude = np.linalg.norm(gradients, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(magnitude > 0, -gradients / magnitude, 0.0)


class RaymarchRenderer:
    """Ray-marching volume renderer, set up once per volume and transfer function.

    Parameters
    ----------
    volume_array : ndarray, shape (nz, ny, nx)
        Scalar volume indexed ``[k, j, i]`` (any real dtype, sampled in that dtype; a read-only array is used as it
        is, anything else is copied). At least 2 voxels per axis.
    spacing : (sx, sy, sz)
        Voxel size in mm; voxel ``(i, j, k)`` sits at ``(i sx, j sy, k sz)`` in the volume frame.
    table : TransferTable
        Colour and opacity per ``table.unit_distance`` mm.
    sample_distance : float, optional
        Distance between samples along each ray in mm (default: half the smallest spacing, like the application's
        VTK mappers). :func:`step_for_samples` converts a sample count into a sample distance.
    lighting : {"emission", "phong", "scatter"}
        Light model (see the module notes).
    light_samples : int
        Samples towards the light per visible sample (``"scatter"``; source 001 used 8).
    light_direction : 3 floats, optional
        Volume-frame vector pointing towards a directional light; default a headlight at the camera.
    ambient, diffuse, specular, specular_power : float
        Blinn-Phong material (VTK's ``vtkVolumeProperty`` defaults 0.1, 0.7, 0.2, 10).
    gradient_threshold : float
        Gradient magnitude (value units per mm) at which shading reaches full strength (``"phong"``).
    early_termination : float or None
        Accumulated opacity in ``(0, 1]`` at which a ray stops; None disables early ray termination.
    empty_space_skipping : bool
        Skip bricks whose values all map to zero opacity (image unchanged).
    brick_size : int
        Cells per brick edge for empty-space skipping.
    scatter_albedo : float
        Fraction of the extinguished light that is scattered, in [0, 1] (``"scatter"``).
    phase : float
        Henyey-Greenstein asymmetry in (-1, 1): 0 isotropic, > 0 forward scattering (``"scatter"``).
    jitter : bool
        Offset each ray's samples by its pixel's jitter (see the module notes); False keeps VTK's unjittered rule.
    progress : callable, optional
        Called with a fraction in [0, 1] during the set-up; may raise OperationCancelled.

    Raises
    ------
    ValueError
        On a volume that is not 3D, has fewer than 2 voxels along an axis, is not real-valued or holds NaN/inf;
        on spacing that is not three positive numbers; on a non-positive or non-finite sample distance; an unknown
        lighting
        model; ``light_samples < 1``; a zero or non-finite light direction; negative material terms or
        gradient threshold, a non-positive specular power; ``early_termination`` outside (0, 1];
        ``brick_size < 1``; ``scatter_albedo`` outside [0, 1] or ``phase`` outside (-1, 1).
    TypeError
        If ``table`` is not a :class:`~algorithms.common.transfer.TransferTable`.
    """

    def __init__(
        self,
        volume_array,
        spacing,
        table: TransferTable,
        *,
        sample_distance: float | None = None,
        lighting: str = "emission",
        light_samples: int = 8,
        light_direction=None,
        ambient: float = 0.1,
        diffuse: float = 0.7,
        specular: float = 0.2,
        specular_power: float = 10.0,
        gradient_threshold: float = 0.0,
        early_termination: float | None = 0.99,
        empty_space_skipping: bool = True,
        brick_size: int = 8,
        scatter_albedo: float = 1.0,
        phase: float = 0.0,
        jitter: bool = False,
        progress: ProgressCallback = None,
    ) -> None:
        checked_table(table)
        self.spacing = validated_spacing(spacing)
        if sample_distance is None:
            sample_distance = 0.5 * float(self.spacing.min())
        sample_distance = validated_distance(sample_distance, "sample_distance")
        checked_lighting(lighting)
        light_samples = validated_count(light_samples, "light_samples")
        if light_direction is not None:
            light = np.asarray(light_direction, dtype=np.float64).reshape(-1)
            if light.shape != (3,) or not np.all(np.isfinite(light)) or not np.linalg.norm(light) > 0:
                raise ValueError(f"light_direction must be a finite non-zero 3-vector, got {light_direction!r}")
            light = light / np.linalg.norm(light)
        else:
            light = np.zeros(3)
        material = {name: _non_negative(name, value) for name, value in
                    (("ambient", ambient), ("diffuse", diffuse), ("specular", specular),
                     ("gradient_threshold", gradient_threshold))}
        specular_power = float(specular_power)
        if not (math.isfinite(specular_power) and specular_power > 0):
            raise ValueError(f"specular_power must be positive, got {specular_power}")
        if early_termination is not None:
            early_termination = float(early_termination)
            if not 0.0 < early_termination <= 1.0:
                raise ValueError(f"early_termination must lie in (0, 1] or be None, got {early_termination}")
        brick_size = validated_count(brick_size, "brick_size")
        scatter_albedo = float(scatter_albedo)
        if not 0.0 <= scatter_albedo <= 1.0:
            raise ValueError(f"scatter_albedo must lie in [0, 1], got {scatter_albedo}")
        phase = float(phase)
        if not -1.0 < phase < 1.0:
            raise ValueError(f"phase (Henyey-Greenstein asymmetry) must lie in (-1, 1), got {phase}")

        volume = sampled_volume(volume_array)
        report(progress, 0.1)
        self.volume = volume
        self.shape = volume.shape
        self.table = table
        self.sample_distance = sample_distance
        self.lighting = lighting
        self.light_samples = light_samples
        self.light_direction = None if light_direction is None else tuple(light)
        self.ambient = material["ambient"]
        self.diffuse = material["diffuse"]
        self.specular = material["specular"]
        self.gradient_threshold = material["gradient_threshold"]
        self.specular_power = specular_power
        self.early_termination = early_termination
        self.empty_space_skipping = bool(empty_space_skipping)
        self.brick_size = brick_size
        self.scatter_albedo = scatter_albedo
        self.phase = phase
        self.jitter = bool(jitter)
        self._light = light

        # Classification: the table corrected for the sample distance, the extinction (per mm) for the light march.
        self._table = np.ascontiguousarray(table.corrected(sample_distance), dtype=np.float32)
        opacity = np.minimum(table.rgba[:, 3].astype(np.float64), _MAX_OPACITY)
        self._extinction = np.ascontiguousarray(-np.log1p(-opacity) / table.unit_distance, dtype=np.float32)
        self._empty_reach = np.zeros((1, 1, 1), dtype=np.int32)
        self._brick_of_cell = np.arange(max(self.shape) - 1, dtype=np.int32) // self.brick_size
        self._tight = np.zeros(6)
        self._any_visible = True
        self._empty_fraction = 0.0
        nz, ny, nx = self.shape
        self._light_box = np.array([0.0, 0.0, 0.0, nx - 1.0, ny - 1.0, nz - 1.0])
        # The bricks also bound the light march (beyond them the extinction is zero), with or without skipping,
        # so switching skipping off leaves every image bit-identical.
        self._classify_bricks(scaled(progress, 0.1, 1.0))
        if self._any_visible:
            self._light_box = self._tight.copy()
        if not self.empty_space_skipping:
            self._empty_fraction = 0.0
        report(progress, 1.0)

    # -- set-up --------------------------------------------------------------------------------------------
    def _classify_bricks(self, progress: ProgressCallback) -> None:
        """Mark the bricks whose value range maps to zero opacity everywhere in the corrected table."""
        low, high = kernels.brick_value_ranges(self.volume, self.brick_size)
        report(progress, 0.8)
        table = self.table
        size = len(self._table)
        # Interpolation between entries e and e + 1 reaches from floor(position(low)) to floor(position(high)) + 1;
        # one more entry on each side absorbs float rounding of the interpolated value.
        first = np.clip(np.floor((low.astype(np.float64) - table.value_min) * table.scale) - 1, 0, size - 1)
        last = np.clip(np.floor((high.astype(np.float64) - table.value_min) * table.scale) + 2, 0, size - 1)
        visible_before = np.concatenate([[0], np.cumsum(self._table[:, 3] > 0)])
        visible = visible_before[last.astype(np.int64) + 1] - visible_before[first.astype(np.int64)] > 0
        self._any_visible = bool(visible.any())
        self._empty_fraction = 1.0 - float(visible.mean())
        if self._any_visible:
            # Chebyshev (chessboard) distance in bricks from each empty brick to the nearest non-empty one: a ray
            # in an empty brick at distance r can leap out of the cube of bricks within distance r - 1.
            reach = distance_transform_cdt(~visible, metric="chessboard")
            self._empty_reach = np.ascontiguousarray(reach, dtype=np.int32)
            nz, ny, nx = self.shape
            kji = np.nonzero(visible)
            b = self.brick_size
            lows = [int(index.min()) * b for index in kji[::-1]]
            highs = [min((int(index.max()) + 1) * b, n - 1) for index, n in zip(kji[::-1], (nx, ny, nz))]
            self._tight = np.array(lows + highs, dtype=np.float64)

    @property
    def empty_brick_fraction(self) -> float:
        """Share of bricks classified empty (0 when empty-space skipping is off)."""
        return self._empty_fraction

    # -- frames --------------------------------------------------------------------------------------------
    def render(self, camera: Camera, width: int, height: int, *, pass_index: int = 0, tools: ToolSet | None = None,
               progress: ProgressCallback = None) -> RenderResult:
        """One frame seen by ``camera`` (volume frame) at ``width`` x ``height`` pixels.

        ``tools`` (:class:`~algorithms.common.cutaway.ToolSet` in the volume frame) cuts the volume away per sample
        (source 002, 2.5 and 3.3.1): removed samples contribute nothing, the cut face is shaded with the tool's
        normal (``"phong"``), removed matter casts no shadow (``"scatter"``); the set-up is untouched, so moving a
        tool costs nothing but the frame.

        ``pass_index`` selects the jitter pass (0 for a still frame; averaging passes 0 .. n - 1 converges towards
        the integral along every ray); it does not matter without jitter.

        Returns
        -------
        RenderResult
            ``rgba`` ``(height, width, 4)`` float32 premultiplied, row 0 at the top; ``stats``: ``seconds``,
            ``rays`` (pixels), ``rays_hit`` (rays through the box), ``samples_per_ray`` (interpolated samples per
            hitting ray), ``early_terminated`` (fraction of hitting rays stopped by early termination),
            ``skipped_fraction`` (share of the samples on the marched stretch of the rays skipped as empty).
        """
        start = time.perf_counter()
        checked_camera(camera)
        width, height = validated_image_size(width, height)
        frame = np.ascontiguousarray(camera.ray_frame(width, height))
        image = np.empty((height, width, 4), dtype=np.float32)
        counts = np.zeros((height, 4), dtype=np.int64)
        termination = self.early_termination if self.early_termination is not None else np.inf
        pass_index = validated_pass(pass_index)
        eye = np.asarray(camera.position, dtype=np.float64)
        threads = numba.get_num_threads()
        packed = packed_tools(tools)
        for band_start in range(0, height, _ROWS_PER_BAND):
            band = np.arange(band_start, min(band_start + _ROWS_PER_BAND, height), dtype=np.int64)
            # Interleave rows so each thread's contiguous share of the prange holds rows from the whole band.
            rows = np.concatenate([band[offset::threads] for offset in range(threads)])
            kernels.render_rows(
                rows, frame, bool(camera.parallel_projection), self.volume, self.spacing, self.sample_distance,
                self._table, float(self.table.value_min), float(self.table.scale), self._extinction, self._empty_reach,
                self._brick_of_cell, self.brick_size, self._tight, self._any_visible, self.empty_space_skipping,
                _LIGHTING_CODES[self.lighting], self._light, self.light_direction is None, self.ambient,
                self.diffuse, self.specular, self.specular_power, self.gradient_threshold, termination,
                self.light_samples, self.scatter_albedo, self.phase, self.jitter, pass_index, eye, self._light_box,
                packed, image, counts,
            )
            report(progress, band[-1] / max(height - 1, 1))
        hits, evaluated, skipped, stopped = (int(v) for v in counts.sum(axis=0))
        marched = evaluated + skipped
        stats = {
            "seconds": time.perf_counter() - start,
            "rays": float(width * height),
            "rays_hit": float(hits),
            "samples_per_ray": evaluated / hits if hits else 0.0,
            "early_terminated": stopped / hits if hits else 0.0,
            "skipped_fraction": skipped / marched if marched else 0.0,
            "tools": float(len(tools)) if tools is not None else 0.0,
        }
        return RenderResult(image, stats)


def raymarch(
    volume_array,
    table: TransferTable,
    camera: Camera,
    width: int,
    height: int,
    *,
    spacing=(1.0, 1.0, 1.0),
    progress: ProgressCallback = None,
    **options,
) -> RenderResult:
    """One frame of :class:`RaymarchRenderer` (set-up included): ``volume_array`` ``(nz, ny, nx)`` seen by
    ``camera`` (volume frame, mm) at ``width`` x ``height``; ``options`` are the renderer's keyword options.

    Returns the :class:`~algorithms.common.render_result.RenderResult` of :meth:`RaymarchRenderer.render`; prefer the
    class when rendering several frames of the same volume.
    """
    renderer = RaymarchRenderer(volume_array, spacing, table, progress=scaled(progress, 0.0, 0.2), **options)
    return renderer.render(camera, width, height, progress=scaled(progress, 0.2, 1.0))


__all__ = [
    "LIGHTING_MODELS",
    "RaymarchRenderer",
    "raymarch",
    "shading_normals",
    "step_for_samples",
]
