"""Direct volume rendering: a volume and a transfer function in, an RGBA frame out, per camera.

- :mod:`.raymarch`: ray marching with emission-absorption, Blinn-Phong or single scattering (sources 001, 002).
- :mod:`.texture_slicing`: view- and axis-aligned texture slicing, float and OpenGL compositing (sources 001, 002).
- :mod:`.shear_warp`: shear-warp with run-length encoding and early termination (source 004).

Each renderer is set up once per volume and transfer function and renders frames with the camera, transfer table
and frame types of :mod:`algorithms.common`; each has an image-output VTK filter derived from
:class:`algorithms.common.render_filter.RendererFilter`. A family imports only :mod:`algorithms.common` and
:mod:`algorithms.compare`, never another family.
"""
