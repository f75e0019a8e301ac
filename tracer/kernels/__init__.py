"""The Warp side of the renderer: named kinds, the structs every kernel reads, and the @wp.func helpers
(intersections, sampling, the camera's rays, materials, lights) that the integrators' kernels call."""
