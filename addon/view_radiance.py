"""The shader node groups "BSGI View Radiance" (where in a baked radiance atlas a shading point
looks, given the direction it is seen from) and "BSGI Texels" (bilinear weights of the four
texels around a point of an image), and the baked material that combines them.

The bake stores, per object, a spatial atlas (faces' tiles, or a NURBS surface's parameter
square) once per angular sample (alpha_i, beta_j) of the disc (20)-(22): an A x A grid of
angular tiles, and for transmitting surfaces a second A x A grid after it (tile rows A .. 2A - 1)
for the lower hemisphere. The group takes the view direction (Geometry > Incoming: towards the viewer, world
space), expresses it in the surface's frame (1)-(3) read from the bake's frame images, maps it
to (alpha, beta) exactly as the core's HemisphereMap::to_disc does (with the pull-in to radius
R), and returns the four neighbouring angular tiles with their bilinear weights.

The images are read with Closest lookups at texel centres and blended here (4 spatial texels x
4 angular tiles): EEVEE gives every Linear lookup mipmaps chosen from screen-space derivatives
of the coordinate, which jump between angular tiles and would average unrelated tiles (and,
minified, neighbouring faces' tiles). Neighbouring angular samples are taken as the nearest
even and the nearest odd sample per axis rather than floor(g) and floor(g) + 1, so a lookup's
tile changes only where its weight is zero."""
from __future__ import annotations

import bpy

VIEW_GROUP = "BSGI View Radiance"
# The same lookup along a given direction: a bumped Lambertian surface's atlas is over its bumped
# normal (bsgi.BumpedLambert), which its material gives (the user's Normal Map or Bump nodes).
NORMAL_GROUP = "BSGI Normal Radiance"
TEXELS_GROUP = "BSGI Texels"
# Bumped when a group's contents change, so files baked by an older add-on get the new groups.
VERSION = 2


class _Builder:
    """Math nodes from sockets and constants, laid out left to right."""

    def __init__(self, tree):
        self.tree = tree
        self.column = 0

    def _node(self, kind):
        node = self.tree.nodes.new(kind)
        node.location = (200 * (self.column // 12), -160 * (self.column % 12))
        self.column += 1
        return node

    def _feed(self, socket, value):
        if isinstance(value, bpy.types.NodeSocket):
            self.tree.links.new(value, socket)
        else:
            socket.default_value = value

    def math(self, operation, *args):
        node = self._node("ShaderNodeMath")
        node.operation = operation
        for socket, value in zip(node.inputs, args):
            self._feed(socket, value)
        return node.outputs[0]

    def vector(self, operation, a, b=None, scale=None):
        node = self._node("ShaderNodeVectorMath")
        node.operation = operation
        self._feed(node.inputs[0], a)
        if b is not None:
            self._feed(node.inputs[1], b)
        if scale is not None:
            self._feed(node.inputs["Scale"], scale)
        return node.outputs["Value" if operation in {"DOT_PRODUCT", "LENGTH"} else "Vector"]

    def separate(self, vector):
        node = self._node("ShaderNodeSeparateXYZ")
        self._feed(node.inputs[0], vector)
        return node.outputs["X"], node.outputs["Y"], node.outputs["Z"]

    def combine(self, x, y, z=0.0):
        node = self._node("ShaderNodeCombineXYZ")
        for socket, value in zip(node.inputs, (x, y, z)):
            self._feed(socket, value)
        return node.outputs[0]


def _disc_coordinates(b, incoming, tangent, normal, radius):
    """(alpha, beta, below): the view direction in the frame (1)-(3), z the normal and x the
    tangent made orthogonal to it (the images interpolate both between texels), through the
    inverse map of |z| (the side is chosen separately, as the core's evaluate_side does)."""
    z = b.vector("NORMALIZE", normal)
    x = b.vector("NORMALIZE", b.vector("SUBTRACT", tangent, b.vector("SCALE", z, scale=b.vector("DOT_PRODUCT", tangent, z))))
    y = b.vector("CROSS_PRODUCT", z, x)
    view = b.vector("NORMALIZE", incoming)
    lx, ly, lz = (b.vector("DOT_PRODUCT", view, axis) for axis in (x, y, z))
    # Unit direction: alpha = x / sqrt(1 + |z|) inside the cone, R x / rho outside it (the
    # pull-in); inside <=> 1 / sqrt(1 + |z|) <= R / rho, so the scale is the smaller of the two.
    q = b.math("ADD", 1.0, b.math("ABSOLUTE", lz))
    rho = b.math("SQRT", b.math("ADD", b.math("MULTIPLY", lx, lx), b.math("MULTIPLY", ly, ly)))
    scale = b.math("MINIMUM", b.math("DIVIDE", 1.0, b.math("SQRT", q)),
                   b.math("DIVIDE", radius, b.math("MAXIMUM", rho, 1e-20)))
    return b.math("MULTIPLY", lx, scale), b.math("MULTIPLY", ly, scale), b.math("LESS_THAN", lz, 0.0)


def _neighbours(b, coordinate, radius, samples):
    """The angular samples around one disc coordinate: [(tile index, weight)] for the nearest
    even and the nearest odd sample of the grid -R + 2R i / (A - 1), i = 0 .. A - 1."""
    last = b.math("SUBTRACT", samples, 1.0)
    g = b.math("MULTIPLY", b.math("DIVIDE", b.math("ADD", coordinate, radius), b.math("MULTIPLY", 2.0, radius)), last)
    g = b.math("MINIMUM", b.math("MAXIMUM", g, 0.0), last)
    even = b.math("MULTIPLY", 2.0, b.math("FLOOR", b.math("MULTIPLY_ADD", g, 0.5, 0.5)))
    odd = b.math("ADD", b.math("MULTIPLY", 2.0, b.math("FLOOR", b.math("MULTIPLY", g, 0.5))), 1.0)
    out = []
    for index in (even, odd):
        weight = b.math("MAXIMUM", b.math("SUBTRACT", 1.0, b.math("ABSOLUTE", b.math("SUBTRACT", g, index))), 0.0)
        out.append((b.math("MINIMUM", index, last), weight))  # past the last sample the weight is 0
    return out


def _new_interface(tree, inputs, outputs):
    tree.nodes.clear()
    for item in list(tree.interface.items_tree):
        tree.interface.remove(item)
    for names, in_out in ((inputs, "INPUT"), (outputs, "OUTPUT")):
        for name, kind in names:
            tree.interface.new_socket(name, in_out=in_out, socket_type=kind)
    group_in, group_out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    group_in.location = (-400, 0)
    return group_in.outputs, group_out


def _numbered(name, kind, count=4):
    return [(f"{name} {k}", kind) for k in range(1, count + 1)]


def _build_texels(tree):
    """UV (in [0, 1]^2 of an image region of Size texels) -> the four texel centres around it
    (UV k, in the same coordinates) and their bilinear weights: what a Linear, Extend lookup
    blends, without mipmaps."""
    i, output = _new_interface(tree, [("UV", "NodeSocketVector"), ("Size", "NodeSocketVector")],
                               _numbered("UV", "NodeSocketVector") + _numbered("Weight", "NodeSocketFloat"))
    b = _Builder(tree)
    axes = []
    for uv, size in list(zip(b.separate(i["UV"]), b.separate(i["Size"])))[:2]:
        last = b.math("SUBTRACT", size, 1.0)
        p = b.math("MINIMUM", b.math("MAXIMUM", b.math("MULTIPLY_ADD", uv, size, -0.5), 0.0), last)
        first = b.math("MINIMUM", b.math("FLOOR", p), b.math("MAXIMUM", b.math("SUBTRACT", size, 2.0), 0.0))
        f = b.math("SUBTRACT", p, first)
        centre = [b.math("DIVIDE", b.math("ADD", first, 0.5 + k), size) for k in (0, 1)]
        axes.append(list(zip(centre, [b.math("SUBTRACT", 1.0, f), f])))
    output.location = (200 * (b.column // 12 + 2), 0)
    for k, ((y, wy), (x, wx)) in enumerate(((ty, tx) for ty in axes[1] for tx in axes[0]), start=1):
        tree.links.new(b.combine(x, y), output.inputs[f"UV {k}"])
        tree.links.new(b.math("MULTIPLY", wx, wy), output.inputs[f"Weight {k}"])


def _build_view(tree, along_input=False):
    """Frame and view direction -> the four angular tiles around the view's (alpha, beta):
    Tile k (the tile's origin in the atlas), Scale (a tile's size in the atlas) and Weight k.
    along_input: the direction is the group's Direction input (world space) instead of the view."""
    i, output = _new_interface(
        tree, [("Tangent", "NodeSocketVector"), ("Normal", "NodeSocketVector"), ("Disc Radius", "NodeSocketFloat"),
               ("Angular Samples", "NodeSocketFloat"), ("Sides", "NodeSocketFloat")]
        + ([("Direction", "NodeSocketVector")] if along_input else []),
        _numbered("Tile", "NodeSocketVector") + _numbered("Weight", "NodeSocketFloat") + [("Scale", "NodeSocketVector")])
    b = _Builder(tree)
    if along_input:
        direction = i["Direction"]
    else:
        geometry = tree.nodes.new("ShaderNodeNewGeometry")
        geometry.location = (-400, -400)
        direction = geometry.outputs["Incoming"]
    radius, samples, sides = i["Disc Radius"], i["Angular Samples"], i["Sides"]
    alpha, beta, below = _disc_coordinates(b, direction, i["Tangent"], i["Normal"], radius)
    # Seen from below: the lower hemisphere's tiles (rows A .. 2A - 1) where the object has
    # them (Sides = 2), black otherwise, as the core's SurfaceRadiance::evaluate.
    shown = b.math("SUBTRACT", 1.0, b.math("MULTIPLY", below, b.math("SUBTRACT", 2.0, sides)))
    row_offset = b.math("MULTIPLY", below, b.math("MULTIPLY", b.math("SUBTRACT", sides, 1.0), samples))
    rows = b.math("MULTIPLY", samples, sides)
    output.location = (200 * (b.column // 12 + 2), 0)
    tree.links.new(b.combine(b.math("DIVIDE", 1.0, samples), b.math("DIVIDE", 1.0, rows)), output.inputs["Scale"])
    k = 0
    for tile_b, weight_b in _neighbours(b, beta, radius, samples):
        for tile_a, weight_a in _neighbours(b, alpha, radius, samples):
            k += 1
            origin = b.combine(b.math("DIVIDE", tile_a, samples), b.math("DIVIDE", b.math("ADD", tile_b, row_offset), rows))
            tree.links.new(origin, output.inputs[f"Tile {k}"])
            tree.links.new(b.math("MULTIPLY", b.math("MULTIPLY", weight_a, weight_b), shown), output.inputs[f"Weight {k}"])


def _group(name, build):
    tree = bpy.data.node_groups.get(name)
    if tree is None:
        tree = bpy.data.node_groups.new(name, "ShaderNodeTree")
    if tree.get("bsgi_version") != VERSION:
        build(tree)
        tree["bsgi_version"] = VERSION
    return tree


class _MaterialBuilder:
    def __init__(self, tree):
        self.tree = tree
        self.row = 0

    def node(self, kind, column, **settings):
        node = self.tree.nodes.new(kind)
        for key, value in settings.items():
            setattr(node, key, value)
        node.location = (250 * column, -180 * self.row)
        return node

    def blend(self, image, lookups, column):
        """Sum of weight * Closest lookup over (uv socket, weight socket) pairs."""
        total = None
        for uv, weight in lookups:
            self.row += 1
            tex = self.node("ShaderNodeTexImage", column, image=image, interpolation="Closest", extension="EXTEND")
            self.tree.links.new(uv, tex.inputs["Vector"])
            scaled = self.node("ShaderNodeVectorMath", column + 1, operation="SCALE")
            self.tree.links.new(tex.outputs["Color"], scaled.inputs[0])
            self.tree.links.new(weight, scaled.inputs["Scale"])
            if total is None:
                total = scaled.outputs["Vector"]
                continue
            add = self.node("ShaderNodeVectorMath", column + 2, operation="ADD")
            self.tree.links.new(total, add.inputs[0])
            self.tree.links.new(scaled.outputs["Vector"], add.inputs[1])
            total = add.outputs["Vector"]
        return total


def _build_normal_view(tree):
    _build_view(tree, along_input=True)


def material(name: str, uv_map: str, atlas, tangent, normal, *, spatial_size, disc_radius: float,
             angular_samples: int, sides: int, detail=None, tint=None, bumped=None):
    """The baked emission material of one object: the frame images and the radiance atlas
    looked up through the groups, at the coordinates of the UV map `uv_map` in the spatial
    atlas of spatial_size = (width, height) texels.

    With detail = (user material, its colour source as textures.colour_source gives it), the
    atlas holds irradiance / pi (the smooth factor) and the material is a copy of the user's,
    whose own colour nodes (image textures at their own resolution and UV maps, procedurals,
    vertex colours) give the albedo it is multiplied by: the decomposition (38) with the
    texture as the detail factor. The copy's shader is left unconnected.

    With tint, the atlas of a textured glossy colour's radiance at f0 = 1 (the atlas holding it at
    f0 = 0), the user's colour nodes give f0 = T instead and the material shows
    atlas + T (tint - atlas): Schlick's Fresnel is affine in f0, so this is the radiance at f0 = T,
    with T at the colour nodes' own resolution. A base colour under a layered coat is blended the
    same way (the atlases at base colour 0 and 1: the surface's radiance is affine in it).

    With bumped, the atlas is over the bumped normal of a Lambertian surface under a normal map
    (bsgi.BumpedLambert) and is looked up along a normal instead of the view: with bumped = (user
    material, its shader node) the material is a copy of the user's whose own nodes feeding the
    shader's Normal input (the normal map at its own resolution) give it; with bumped = "flat",
    the surface's own normal (its bumps not shown)."""
    old = bpy.data.materials.get(name)
    user = detail[0] if detail is not None else bumped[0] if isinstance(bumped, tuple) else None
    if user is not None:
        if old is not None:
            bpy.data.materials.remove(old)
        mat = user.copy()
        mat.name = name
        for node in [n for n in mat.node_tree.nodes if n.type == "OUTPUT_MATERIAL"]:
            mat.node_tree.nodes.remove(node)
    else:
        mat = old or bpy.data.materials.new(name)
    mat.use_fake_user = True  # kept in the .blend while the originals are shown
    if mat.node_tree is None:
        mat.use_nodes = True
    tree = mat.node_tree
    if user is None:
        tree.nodes.clear()
    link = tree.links.new
    m = _MaterialBuilder(tree)
    uv = m.node("ShaderNodeUVMap", 0, uv_map=uv_map)
    texels = m.node("ShaderNodeGroup", 1, node_tree=_group(TEXELS_GROUP, _build_texels))
    link(uv.outputs["UV"], texels.inputs["UV"])
    texels.inputs["Size"].default_value = (*spatial_size, 1.0)
    spatial = [(texels.outputs[f"UV {k}"], texels.outputs[f"Weight {k}"]) for k in range(1, 5)]
    view = m.node("ShaderNodeGroup", 5, node_tree=_group(NORMAL_GROUP, _build_normal_view) if bumped is not None
                  else _group(VIEW_GROUP, _build_view))
    view.inputs["Disc Radius"].default_value = disc_radius
    view.inputs["Angular Samples"].default_value = angular_samples
    view.inputs["Sides"].default_value = sides
    lookups = []
    for k in range(1, 5):
        for uv_s, weight_s in spatial:
            m.row += 1
            at = m.node("ShaderNodeVectorMath", 6, operation="MULTIPLY_ADD")
            link(uv_s, at.inputs[0])
            link(view.outputs["Scale"], at.inputs[1])
            link(view.outputs[f"Tile {k}"], at.inputs[2])
            weight = m.node("ShaderNodeMath", 7, operation="MULTIPLY")
            link(weight_s, weight.inputs[0])
            link(view.outputs[f"Weight {k}"], weight.inputs[1])
            lookups.append((at.outputs["Vector"], weight.outputs[0]))
    m.row = 0
    # The atlas's lookups come first among the material's image nodes: the radiance image is
    # the first TEX_IMAGE node, as in a diffuse bake's material.
    total = m.blend(atlas, lookups, 8)
    m.row = 0
    link(m.blend(tangent, spatial, 2), view.inputs["Tangent"])
    frame_normal = m.blend(normal, spatial, 2)
    link(frame_normal, view.inputs["Normal"])
    if bumped is not None:
        # The copy's own node feeding its shader's Normal input (the user's normal map), else flat.
        shader = tree.nodes[bumped[1].name] if isinstance(bumped, tuple) else None
        source = None if shader is None else next((lk.from_socket for lk in shader.inputs["Normal"].links
                                                   if lk.is_valid and not lk.is_muted), None)
        link(source if source is not None else frame_normal, view.inputs["Direction"])
    emission = m.node("ShaderNodeEmission", 11)
    if detail is not None:
        # albedo = the user's colour x diffuse weight + specular, as the solve's albedo texture.
        node, colour, weight, specular = detail[1]
        source = next(link.from_socket for link in tree.nodes[node.name].inputs[colour].links
                      if link.is_valid and not link.is_muted)
        albedo = m.node("ShaderNodeVectorMath", 9, operation="MULTIPLY_ADD")
        link(source, albedo.inputs[0])
        albedo.inputs[1].default_value = (weight,) * 3
        albedo.inputs[2].default_value = specular
        if tint is None:
            shown = m.node("ShaderNodeVectorMath", 10, operation="MULTIPLY")
            link(total, shown.inputs[0])
            link(albedo.outputs["Vector"], shown.inputs[1])
        else:
            # f0 clamped to [0, 1] as the solve's specular texture.
            low = m.node("ShaderNodeVectorMath", 9, operation="MAXIMUM")
            link(albedo.outputs["Vector"], low.inputs[0])
            low.inputs[1].default_value = (0.0, 0.0, 0.0)
            f0 = m.node("ShaderNodeVectorMath", 9, operation="MINIMUM")
            link(low.outputs["Vector"], f0.inputs[0])
            f0.inputs[1].default_value = (1.0, 1.0, 1.0)
            m.row = 16
            difference = m.node("ShaderNodeVectorMath", 10, operation="SUBTRACT")
            link(m.blend(tint, lookups, 8), difference.inputs[0])
            link(total, difference.inputs[1])
            shown = m.node("ShaderNodeVectorMath", 10, operation="MULTIPLY_ADD")
            link(difference.outputs["Vector"], shown.inputs[0])
            link(f0.outputs["Vector"], shown.inputs[1])
            link(total, shown.inputs[2])
        total = shown.outputs["Vector"]
    link(total, emission.inputs["Color"])
    out = m.node("ShaderNodeOutputMaterial", 12)
    link(emission.outputs["Emission"], out.inputs["Surface"])
    return mat
