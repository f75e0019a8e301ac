"""Random numbers keyed by (seed, pixel, sample), and the pure sample warps.

Only kernels create RNG state: ``rng_start(seed, pixel, sample)`` hashes the key into a PCG
state, and each later draw (``wp.randf``) is the next dimension of that sample. An image
therefore never depends on threads, tiles or how samples are split into passes.
Warps take their uniform numbers as arguments (u1, u2 in [0, 1)), so tests can call them
with chosen values.
"""

import warp as wp

from tracer.kernels.geometry import PI, basis
from tracer.kernels.kinds import FILTER_BOX, SAMPLER_CENTER, SAMPLER_GRID, SAMPLER_LOWDISCREPANCY, SAMPLER_RANDOM
from tracer.kernels.structs import SceneData

INV_PI = wp.constant(1.0 / 3.14159265358979323846)  # a product where a quotient would wait for the divider
PCG_MUL = wp.constant(wp.uint32(747796405))
PCG_INC = wp.constant(wp.uint32(2891336453))
PCG_OUT = wp.constant(wp.uint32(277803737))


@wp.func
def pcg_hash(v: wp.uint32) -> wp.uint32:
    """PCG-RXS-M-XS hash (Jarzynski & Olano 2020, 'Hash Functions for GPU Rendering')."""
    state = v * PCG_MUL + PCG_INC
    word = ((state >> ((state >> wp.uint32(28)) + wp.uint32(4))) ^ state) * PCG_OUT
    return (word >> wp.uint32(22)) ^ word


@wp.func
def pixel_key(seed: int, pixel: int) -> wp.uint32:
    """A hash of (seed, pixel) that keys the low-discrepancy dimensions of that pixel's samples."""
    return pcg_hash(pcg_hash(wp.uint32(seed) ^ GOLDEN) ^ wp.uint32(pixel))


@wp.func
def rng_start(seed: int, pixel: int, sample: int) -> wp.uint32:
    """RNG state of one pixel sample; the n-th wp.randf of it is dimension n."""
    h = pcg_hash(wp.uint32(seed))
    h = pcg_hash(h ^ wp.uint32(pixel))
    h = pcg_hash(h ^ wp.uint32(sample))
    return h


R2_A1 = wp.constant(wp.uint32(3242174889))  # 2^32 / plastic number: Roberts' R2 sequence, 1st axis
R2_A2 = wp.constant(wp.uint32(2447445413))  # 2^32 / plastic number^2, 2nd axis
U24 = wp.constant(1.0 / 16777216.0)
GOLDEN = wp.constant(wp.uint32(0x9E3779B9))  # 2^32 / golden ratio: keeps pixel keys apart from rng states
LK_1 = wp.constant(wp.uint32(0x6C50B47C))  # the Laine-Karras hash's constants, as Burley 2020 improved them
LK_2 = wp.constant(wp.uint32(0xB82F1E52))
LK_3 = wp.constant(wp.uint32(0xC7AFE638))
LK_4 = wp.constant(wp.uint32(0x8D22F6E6))
MASK_1 = wp.constant(wp.uint32(0x55555555))  # reverse_bits: swap bits, pairs, nibbles, bytes, halves
MASK_2 = wp.constant(wp.uint32(0x33333333))
MASK_4 = wp.constant(wp.uint32(0x0F0F0F0F))
MASK_8 = wp.constant(wp.uint32(0x00FF00FF))
SOBOL_M1 = wp.constant(wp.uint32(0xAAAAAAAA))  # bit positions k with bit 0 of k set (sobol1_reversed)
SOBOL_M2 = wp.constant(wp.uint32(0xCCCCCCCC))  # ... with bit 1 set
SOBOL_M4 = wp.constant(wp.uint32(0xF0F0F0F0))
SOBOL_M8 = wp.constant(wp.uint32(0xFF00FF00))
SOBOL_M16 = wp.constant(wp.uint32(0xFFFF0000))


@wp.func
def reverse_bits(x: wp.uint32) -> wp.uint32:
    """The 32 bits of x in reverse order."""
    x = ((x >> wp.uint32(1)) & MASK_1) | ((x & MASK_1) << wp.uint32(1))
    x = ((x >> wp.uint32(2)) & MASK_2) | ((x & MASK_2) << wp.uint32(2))
    x = ((x >> wp.uint32(4)) & MASK_4) | ((x & MASK_4) << wp.uint32(4))
    x = ((x >> wp.uint32(8)) & MASK_8) | ((x & MASK_8) << wp.uint32(8))
    return (x >> wp.uint32(16)) | (x << wp.uint32(16))


@wp.func
def laine_karras(x: wp.uint32, seed: wp.uint32) -> wp.uint32:
    """A hash keyed by `seed` in which each bit of x depends only on that bit and the bits below it:
    on bit-reversed numbers, Owen's nested uniform scrambling (Laine and Karras 2011, with the
    constants of Burley 2020)."""
    x = x + seed
    x = x ^ (x * LK_1)
    x = x ^ (x * LK_2)
    x = x ^ (x * LK_3)
    x = x ^ (x * LK_4)
    return x


@wp.func
def shuffle(index: wp.uint32, seed: wp.uint32) -> wp.uint32:
    """A permutation of the sample indices keyed by `seed` that maps every aligned block of 2^k indices
    onto an aligned block of 2^k (Owen scrambling of the index's bits, Burley 2020)."""
    return reverse_bits(laine_karras(reverse_bits(index), seed))


@wp.func
def sobol1_reversed(n: wp.uint32) -> wp.uint32:
    """The second dimension of Sobol's sequence at index n, its 32 bits reversed: bit j is the parity of
    the index bits k that contain j (k & j == j), since its direction numbers are the rows of Pascal's
    triangle mod 2 (Lucas). Five shifts instead of a loop over the index's bits."""
    r = n
    r = r ^ ((r & SOBOL_M1) >> wp.uint32(1))
    r = r ^ ((r & SOBOL_M2) >> wp.uint32(2))
    r = r ^ ((r & SOBOL_M4) >> wp.uint32(4))
    r = r ^ ((r & SOBOL_M8) >> wp.uint32(8))
    r = r ^ ((r & SOBOL_M16) >> wp.uint32(16))
    return r


@wp.func
def sample_2d(key: wp.uint32, dim: int, index: int) -> wp.vec2:
    """Point `index` of Roberts' R2 low-discrepancy sequence, shifted (Cranley-Patterson rotation) by
    a random offset keyed by (key, dim), its index shuffled by the same key: successive samples of
    one pixel fill [0,1)^2 evenly for each dimension pair (the first 2^k of them are 2^k successive
    points of the sequence), while pixels and dimensions stay independent. Without the shuffle every
    dimension pair would take the same points in the same order, only shifted: the path's
    successive bounces would be correlated, and a pixel's error would stop falling with more samples.
    Fixed-point arithmetic keeps it exact for any index."""
    h = pcg_hash(key ^ pcg_hash(wp.uint32(dim)))
    h2 = pcg_hash(h)
    i = shuffle(wp.uint32(index), h2 ^ GOLDEN)
    x = h + i * R2_A1
    y = h2 + i * R2_A2
    return wp.vec2(float(x >> wp.uint32(8)) * U24, float(y >> wp.uint32(8)) * U24)


@wp.func
def sobol_2d(key: wp.uint32, dim: int, index: int) -> wp.vec2:
    """Point `index` of a pixel's 2D low-discrepancy sequence for dimension pair `dim` (the camera's,
    for the lowdiscrepancy sampler): the first two dimensions of Sobol's sequence, Owen-scrambled
    (nested uniform scrambling, each coordinate with its own seed keyed by (key, dim)), its index
    shuffled by the same key (Burley 2020, "Practical Hash-based Owen Scrambling"). Any first 2^k
    samples of a pixel form a (0, k, 2)-net: one point in every box of 2^-a x 2^-b with a + b = k (2x2
    cells at 4 samples, 4x4 at 16, and the strips between): stratified like a jittered grid, and in
    thin strips too, at every power of two on the way; pixels and dimension pairs stay independent.
    About twice sample_2d's cost: the path's bounces keep R2, since these points gave them no less
    error (BENCHMARKS.md)."""
    h = pcg_hash(key ^ pcg_hash(wp.uint32(dim)))
    h2 = pcg_hash(h)
    n = shuffle(wp.uint32(index), h2 ^ GOLDEN)
    x = reverse_bits(laine_karras(n, h))
    y = reverse_bits(laine_karras(sobol1_reversed(n), pcg_hash(h2)))
    return wp.vec2(float(x >> wp.uint32(8)) * U24, float(y >> wp.uint32(8)) * U24)


# The camera's low-discrepancy dimensions (sobol_2d) for the lowdiscrepancy sampler; the path
# integrator's bounces take theirs from 1024 on (integrators/path.py, DIMS_PER_BOUNCE)
DIM_FILM = wp.constant(0)  # the film position
DIM_LENS = wp.constant(1)  # the point of the lens (depth of field)
DIM_TIME = wp.constant(2)  # the shutter time (motion blur): the first coordinate


@wp.func
def film_uniforms(sampler: int, key: wp.uint32, sample: int, rng: wp.uint32):
    """The two uniform numbers (u1, u2) that place sample `sample` in its pixel, and the random state
    after its two draws (made for every sampler, so the draws after them are the same): the draws
    themselves, or for the lowdiscrepancy sampler the pixel's point `sample` (sobol_2d, keyed by the
    pixel's `key`)."""
    state = wp.uint32(rng)
    u1 = wp.randf(state)
    u2 = wp.randf(state)
    if sampler == SAMPLER_LOWDISCREPANCY:
        p = sobol_2d(key, DIM_FILM, sample)
        u1 = p[0]
        u2 = p[1]
    return u1, u2, state


@wp.func
def film_offset(sampler: int, sample: int, spp: int, u1: float, u2: float) -> wp.vec2:
    """Position (u, v) in [0,1)^2 inside the pixel of sample `sample` of `spp`.

    center: the pixel centre; grid: centres of a sqrt(spp) x sqrt(spp) grid; random: (u1, u2);
    jittered: one random point in each grid cell (stratified, Cook 1986); lowdiscrepancy: (u1, u2) as
    film_uniforms draws them, a point of the pixel's low-discrepancy sequence.
    """
    if sampler == SAMPLER_CENTER:
        return wp.vec2(0.5, 0.5)
    if sampler == SAMPLER_RANDOM or sampler == SAMPLER_LOWDISCREPANCY:
        return wp.vec2(u1, u2)
    n = int(wp.floor(wp.sqrt(float(spp)) + 0.5))
    i = sample % n
    j = sample / n
    if sampler == SAMPLER_GRID:
        return wp.vec2((float(i) + 0.5) / float(n), (float(j) + 0.5) / float(n))
    return wp.vec2((float(i) + u1) / float(n), (float(j) + u2) / float(n))


@wp.func(inline=True)
def filter_offset(scene: SceneData, uv: wp.vec2):
    """Film offset inside the pixel, and the sample's weight, by filter importance sampling.

    The offsets follow |f| (one inverse-CDF table per axis, f separable), so each sample stays
    in its own pixel's sum; a sample where f < 0 (Mitchell's lobes) gets a negative weight.
    """
    if scene.filter == FILTER_BOX:
        r = scene.filter_radius
        return wp.vec2(0.5 + (uv[0] - 0.5) * 2.0 * r, 0.5 + (uv[1] - 0.5) * 2.0 * r), 1.0
    n = scene.filter_icdf.shape[0]
    w = scene.filter_norm
    off = wp.vec2(0.0)
    for k in range(2):
        x = uv[k] * float(n - 1)
        i = wp.min(int(x), n - 2)
        f = x - float(i)
        off[k] = 0.5 + (1.0 - f) * scene.filter_icdf[i] + f * scene.filter_icdf[i + 1]
        w = w * scene.filter_sign[wp.min(int(x + 0.5), n - 1)]
    return off, w


@wp.func
def stratum(k: int, n: int, u1: float, u2: float) -> wp.vec2:
    """Sample k of n in [0,1)^2, stratified: a jittered grid when n is a square, else strips in u."""
    m = int(wp.floor(wp.sqrt(float(n)) + 0.5))
    if m * m == n:
        return wp.vec2((float(k % m) + u1) / float(m), (float(k / m) + u2) / float(m))
    return wp.vec2((float(k) + u1) / float(n), u2)


@wp.func
def concentric_disk(u1: float, u2: float) -> wp.vec2:
    """Uniform point of the unit disk, area-preserving (Shirley & Chiu 1997)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return wp.vec2(0.0, 0.0)
    r = float(0.0)
    phi = float(0.0)
    if wp.abs(a) > wp.abs(b):
        r = a
        phi = (PI / 4.0) * (b / a)
    else:
        r = b
        phi = PI / 2.0 - (PI / 4.0) * (a / b)
    return wp.vec2(r * wp.cos(phi), r * wp.sin(phi))


@wp.func
def to_world(local: wp.vec3, n: wp.vec3) -> wp.vec3:
    """A direction given about the z axis, turned so that z becomes the unit vector n."""
    t, b = basis(n)
    return local[0] * t + local[1] * b + local[2] * n


@wp.func
def sample_cosine_hemisphere(u1: float, u2: float) -> wp.vec3:
    """Cosine-weighted direction about +z (Malley's method): pdf = cos(theta) / pi."""
    d = concentric_disk(u1, u2)
    return wp.vec3(d[0], d[1], wp.sqrt(wp.max(0.0, 1.0 - d[0] * d[0] - d[1] * d[1])))


@wp.func
def cosine_hemisphere_pdf(cos_theta: float) -> float:
    return wp.max(cos_theta, 0.0) * INV_PI


@wp.func
def sample_cos_lobe(u1: float, u2: float, m: float) -> wp.vec3:
    """Direction about +z with density proportional to cos^m(alpha): pdf = (m+1)/(2 pi) cos^m."""
    cos_a = wp.pow(u1, 1.0 / (m + 1.0))
    sin_a = wp.sqrt(wp.max(0.0, 1.0 - cos_a * cos_a))
    phi = 2.0 * PI * u2
    return wp.vec3(sin_a * wp.cos(phi), sin_a * wp.sin(phi), cos_a)


@wp.func
def cos_lobe_pdf(cos_a: float, m: float) -> float:
    if cos_a <= 0.0:
        return 0.0
    return (m + 1.0) / (2.0 * PI) * wp.pow(cos_a, m)


@wp.func
def phong_lobes_pdf(pd: float, ps: float, shininess: float, n: wp.vec3, r: wp.vec3, wi: wp.vec3) -> float:
    """Density of direction wi under the mixture of the diffuse lobe (cosine about n, chosen with
    probability pd) and the Phong lobe (cos^shininess about the mirror direction r, probability ps)."""
    pdf = pd * cosine_hemisphere_pdf(wp.dot(n, wi))
    if ps > 0.0:
        pdf += ps * cos_lobe_pdf(wp.dot(r, wi), shininess)
    return pdf


@wp.func
def power_heuristic(nf: float, pf: float, ng: float, pg: float) -> float:
    """Multiple importance sampling weight of a sample from strategy f (nf samples of density pf)
    against strategy g (ng samples of density pg), power 2 (Veach & Guibas 1995). An infinite density
    (a sphere light too small to see from afar in float32: its cone has no width) weighs 1, as in pbrt-v4,
    where inf / inf would be NaN."""
    a = nf * pf
    b = ng * pg
    if a <= 0.0:
        return 0.0
    if wp.isinf(a * a):
        return 1.0
    return (a * a) / (a * a + b * b)


@wp.func
def sample_cone(u1: float, u2: float, cos_max: float) -> wp.vec3:
    """Uniform direction about +z within angle acos(cos_max): pdf = 1 / (2 pi (1 - cos_max))."""
    cos_a = 1.0 - u1 * (1.0 - cos_max)
    sin_a = wp.sqrt(wp.max(0.0, 1.0 - cos_a * cos_a))
    phi = 2.0 * PI * u2
    return wp.vec3(sin_a * wp.cos(phi), sin_a * wp.sin(phi), cos_a)
