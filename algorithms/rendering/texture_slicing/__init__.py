"""Direct volume rendering by texture slicing: view-aligned and axis-aligned stacks of textured polygons.

Method
------
The volume is drawn as a stack of semi-transparent polygons, composited back to front with the over operator
(source 001, technique 3; source 002, 2.4.2-2.4.3)::

    C = C_front * a + C_back * (1 - a)

1. **Slice geometry.** *View-aligned* (source 001; source 002, fig. 2.6): ``count`` planes perpendicular to the
   camera's view direction ``f`` between the nearest and the farthest corner of the box. The depth range
   ``[d_near, d_far]`` is cut into ``count`` slabs of equal thickness ``delta = (d_far - d_near) / count`` and a
   plane is put through the middle of each slab, so no plane merely touches a corner. Each plane is intersected
   with the 12 edges of the box; the cut points form a convex polygon of 3 to 6 vertices. Source 001 orders them
   by solving a travelling-salesman problem (the shortest closed tour, brute force, ``n <= 6``); sorting by angle
   around the centroid gives the same cycle (the tests check it against a brute-force tour).
   Vertices are ordered counter-clockwise as seen from the camera and triangulated as a fan ``(0, i, i + 1)``;
   each carries its 3D texture coordinate, its position normalised to the box. *Axis-aligned* (source 002,
   fig. 2.5): of the three stacks of slices along x, y and z, the one along the axis with the largest
   ``|f_axis|`` is drawn, one slice through every layer of voxel centres, back to front; the stack switches when
   the largest component changes, and because the two stacks sample the volume at different points the picture
   jumps (source 002's flicker).
2. **Slice textures.** Each slice gets a 2D RGBA texture in its own plane frame: every texel holds the
   trilinearly interpolated scalar at its centre mapped through the transfer function, with the opacity corrected
   for the distance between slices along the view direction (``delta`` for view-aligned slices,
   ``s_axis / |f_axis|`` for axis-aligned ones), as *premultiplied* (associated) colour ``(a r, a g, a b, a)``,
   which interpolates correctly (bilinear filtering of straight colour would mix the colour of transparent texels
   into the border of visible ones). Texel grids: by default a view-aligned slice gets one texel per pixel, its
   centre where the pixel's ray meets the slice, so the texture has the resolution of source 002's 3D texture
   sampled per fragment (its transfer function is looked up per fragment too) and bilinear filtering reads texel
   centres exactly. With ``texel_size`` the grid is anchored at the polygon's corner instead (what a coarser 2D
   texture costs); axis-aligned slices use the voxel grid of their layer (the classic 2D-texture method, bilinear
   within the layer only).
3. **Compositing**, two ways over exactly the same slices and textures:

   - *rasterising* (:class:`SliceStackProp`): one VTK actor per slice, its polygon as fan triangles with 2D
     texture coordinates, an RGBA ``unsigned char`` texture with linear filtering, drawn back to front into the
     render window's 8-bit framebuffer with the blend function ``(ONE, ONE_MINUS_SRC_ALPHA)`` that VTK sets for
     premultiplied textures: ``C = (a c)_front + C_back (1 - a)``, the formula above. Depth writes are off for
     translucent actors in VTK, and the renderer's order-independent translucency must be off (it would replace
     the over operator by a weighted average), as must depth peeling; :meth:`SliceStackProp.attach` sees to it.
   - *float reference* (:class:`SlicingRenderer`): the same formula in float32 per pixel: the pixel's ray meets
     each slice plane at one point (exactly the point whose texture coordinate the rasteriser interpolates
     perspective-correctly), the texture is sampled there bilinearly (clamped to its edge, like GL's
     ``CLAMP_TO_EDGE``), and the sample is composited if the point lies in the polygon, i.e. in the box. With
     ``precision="uint8"`` the accumulation buffer is rounded to 8 bits after every slice, as a framebuffer
     does: source 002 (2.4.3, citing [MB05]) reports errors of up to 40 % after a hundred slices.

Default slice distance (view-aligned): one slice per smallest voxel spacing along the view direction, i.e.
``count = ceil((d_far - d_near) / min(sx, sy, sz))``, so the slices are ``delta <= min(sx, sy, sz)`` apart;
``slice_distance`` (mm) or ``slices`` (a count) choose another.

Known approximation: the opacity is corrected for the distance between slices along the central view direction;
for a perspective camera a ray ``theta`` off axis crosses the slabs ``delta / cos(theta)`` apart, so its opacity
is underestimated towards the image corners (by a factor ``cos(theta)``, 0.94 at the corners of a 30 degree view),
as with every planar slice stack on graphics hardware.

Axis order: volume arrays are ``(nz, ny, nx)``, indexed ``[k, j, i]``; spacing and points are ``(x, y, z)`` =
``(i, j, k)``. Everything is in the *volume frame*: voxel ``(i, j, k)`` at ``(i sx, j sy, k sz)`` mm; the box is
the one VTK's volume mappers render, from the first to the last voxel centre.

References
----------
Source 001 (Dutch student report comparing three techniques for rendering volumetric data, see docs/references.md),
"Techniek 3: Texture slicing" (plane-box intersection with the 12 edges, vertex order as a travelling-salesman
tour, triangle fans, back-to-front blending ``C = C_voor a + C_achter (1 - a)``). Source 002 (Kähler, *Vergleich
von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009), sections 2.4.1-2.4.3 (transfer function lookup,
3D textures, compositing textured polygons: three axis-aligned stacks switched by the largest component of the
view vector, view-aligned polygons of three to six vertices, 8-bit framebuffer error).

K. Engel, M. Hadwiger, J. Kniss, C. Rezk-Salama, D. Weiskopf, "Real-Time Volume Graphics", A K Peters, 2006
(source 002's [EHK+06]), chapter 3: 2D and 3D texture-based slicing, associated colours.
B. Cabral, N. Cam, J. Foran, "Accelerated volume rendering and tomographic reconstruction using texture mapping
hardware", Proc. Symposium on Volume Visualization 1994, 91-98. DOI 10.1145/197938.197972.

Modules: :mod:`.geometry` (slice polygons), :mod:`.textures` (texel grids of a frame), :mod:`.kernels` (numba
resampling and compositing), :mod:`.renderer` (:class:`SlicingRenderer`, the float path), :mod:`.gl_prop`
(:class:`SliceStackProp`, the OpenGL path), :mod:`.filter` (:class:`TextureSlicingFilter`, image out).

Examples
--------
>>> slicer = SlicingRenderer(volume.array, volume.spacing, table)            # view-aligned, float compositing
>>> frame = slicer.render(camera, 512, 512)                                  # camera in the volume frame
>>> stack = SliceStackProp(slicer, user_matrix=volume.local_to_world)        # the same slices as VTK actors
>>> stack.attach(vtk_renderer)
>>> stack.update(camera, 512, 512)                                           # after every camera move
"""

from .filter import TextureSlicingFilter
from .geometry import (
    MAX_POLYGON_VERTICES,
    MODES,
    SlicePolygons,
    axis_aligned_slices,
    default_slice_count,
    slice_polygons,
    slices_to_polydata,
)
from .gl_prop import SliceStackProp
from .renderer import PRECISIONS, SlicingRenderer
from .textures import CHUNK_TEXELS, SliceLayout, SliceTexture, TextureChunk, layout_stats

__all__ = [
    "CHUNK_TEXELS",
    "MAX_POLYGON_VERTICES",
    "MODES",
    "PRECISIONS",
    "SliceLayout",
    "SlicePolygons",
    "SliceStackProp",
    "SliceTexture",
    "SlicingRenderer",
    "TextureChunk",
    "TextureSlicingFilter",
    "axis_aligned_slices",
    "default_slice_count",
    "layout_stats",
    "slice_polygons",
    "slices_to_polydata",
]
