"""The ray-tree record: where an integrator's `trace` writes each ray as a node when asked.

The image kernels pass a record with cap 0 and record = 0, so the same @wp.func code makes the
image and the tree; tracer/rendering/raytree.py decodes the arrays into the JSON of docs/scene-format.md.
Every writer but `begin_node` does nothing for node -1 (not recorded, or past the cap), so an
integrator calls them unconditionally and never touches the layout.
"""

import warp as wp

from tracer.kernels.geometry import Hit
from tracer.kernels.kinds import END_ABSORBED, END_LIGHT, END_MISS, END_NONE, RAY_SHADOW
from tracer.kernels.structs import struct

# Node record layout: integers, vectors and floats per node.
I_KIND, I_DEPTH, I_PARENT, I_HIT, I_OBJ, I_MAT, I_FRONT, I_LIGHT, I_OCCLUDED, I_END = range(10)
V_ORIGIN, V_DIR, V_POINT, V_NORMAL, V_WEIGHT, V_AMBIENT, V_DIFFUSE, V_SPECULAR, V_EMISSION, V_CARRIED, V_K = range(11)
F_T, F_FOG, F_TIME = range(3)
NUM_I, NUM_V, NUM_F = 10, 11, 3


@struct
class TreeRecord:
    """Where `trace` writes the nodes of one sample's tree (record = 1), or a dummy."""

    count: wp.array(dtype=wp.int32)  # [0]: nodes written (may exceed cap: truncated)
    cap: int
    ints: wp.array2d(dtype=wp.int32)  # (cap, NUM_I)
    vecs: wp.array2d(dtype=wp.vec3)  # (cap, NUM_V)
    floats: wp.array2d(dtype=wp.float32)  # (cap, NUM_F)


@wp.func(inline=True)
def begin_node(
    rec: TreeRecord, kind: int, depth: int, parent: int, o: wp.vec3, d: wp.vec3, w: wp.vec3, k: wp.vec3, time: float
) -> int:
    """A new node for the ray (o, d) of RAY_* `kind`, child of `parent` (-1: the root), with weight w (the
    product of K's from the eye) and its own factor k: its index, or -1 past the cap."""
    node = wp.atomic_add(rec.count, 0, 1)
    if node >= rec.cap:
        return -1
    rec.ints[node, I_KIND] = kind
    rec.ints[node, I_DEPTH] = depth
    rec.ints[node, I_PARENT] = parent
    rec.ints[node, I_HIT] = 0
    rec.ints[node, I_OBJ] = -1
    rec.ints[node, I_MAT] = -1
    rec.ints[node, I_LIGHT] = -1
    rec.ints[node, I_OCCLUDED] = -1
    rec.ints[node, I_END] = END_NONE
    rec.vecs[node, V_ORIGIN] = o
    rec.vecs[node, V_DIR] = d
    rec.vecs[node, V_WEIGHT] = w
    rec.vecs[node, V_K] = k
    for j in range(V_POINT, V_K):
        if j != V_WEIGHT:
            rec.vecs[node, j] = wp.vec3(0.0)
    rec.floats[node, F_T] = -1.0
    rec.floats[node, F_FOG] = 1.0
    rec.floats[node, F_TIME] = time
    return node


@wp.func(inline=True)
def record_hit(
    rec: TreeRecord, node: int, t: float, p: wp.vec3, n: wp.vec3, obj: int, mat: int, front: int, fog: float
):
    """The ray's hit at distance t: point, shading normal n, object, material, side, fog transmittance."""
    if node >= 0:
        rec.ints[node, I_HIT] = 1
        rec.ints[node, I_OBJ] = obj
        rec.ints[node, I_MAT] = mat
        rec.ints[node, I_FRONT] = front
        rec.floats[node, F_T] = t
        rec.floats[node, F_FOG] = fog
        rec.vecs[node, V_POINT] = p
        rec.vecs[node, V_NORMAL] = n


@wp.func(inline=True)
def record_terms(rec: TreeRecord, node: int, emission: wp.vec3, ambient: wp.vec3, diffuse: wp.vec3, specular: wp.vec3):
    if node >= 0:
        rec.vecs[node, V_EMISSION] = emission
        rec.vecs[node, V_AMBIENT] = ambient
        rec.vecs[node, V_DIFFUSE] = diffuse
        rec.vecs[node, V_SPECULAR] = specular


@wp.func(inline=True)
def record_miss(rec: TreeRecord, node: int, fog: int):
    """The ray left the scene (in fog its transmittance is 0: it returns the fog colour)."""
    if node >= 0:
        rec.ints[node, I_END] = END_MISS
        rec.floats[node, F_FOG] = wp.where(fog != 0, 0.0, 1.0)


@wp.func(inline=True)
def record_end(rec: TreeRecord, node: int, end: int):
    """Why the ray has no more children (END_*)."""
    if node >= 0:
        rec.ints[node, I_END] = end


@wp.func(inline=True)
def record_shadow(
    rec: TreeRecord,
    node: int,
    depth: int,
    so: wp.vec3,
    l: wp.vec3,
    w: wp.vec3,
    time: float,
    li: int,
    occluder: Hit,
    carried: wp.vec3,
):
    """A shadow ray from so towards light li, child of `node`: the occluder it met (its normal turned
    towards the ray), or what it carried from the light (E f cos(theta))."""
    if node >= 0:
        sn = begin_node(rec, RAY_SHADOW, depth, node, so, l, w, wp.vec3(1.0), time)
        if sn >= 0:
            rec.ints[sn, I_LIGHT] = li
            rec.ints[sn, I_OCCLUDED] = occluder.hit
            if occluder.hit != 0:
                front = wp.dot(l, occluder.ng) < 0.0
                n = wp.where(front, occluder.ng, -occluder.ng)
                record_hit(rec, sn, occluder.t, occluder.p, n, occluder.obj, occluder.mat, wp.where(front, 1, 0), 1.0)
                rec.ints[sn, I_END] = END_ABSORBED
            else:
                rec.vecs[sn, V_CARRIED] = carried
                rec.ints[sn, I_END] = END_LIGHT
