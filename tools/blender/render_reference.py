"""Cycles reference renders of a glTF model on a shadow catcher, lit only by an equirect map.

The ground truth for odvr's renderer. Run headless with
Debian's Blender 3.4.1 (CPU Cycles, no denoiser):

  one image:
    blender -b --factory-startup --python tools/blender/render_reference.py -- \
        --car media/demo/car.glb --env ../shared/data/env/sky.exr \
        --camera 5.2,1.9,4.4,0,0.55,0,30 --size 320x180 --spp 256 --material glossy --out /tmp/ref/sky_glossy

  the committed set (media/reference/, see media/README.md):
    blender -b --factory-startup --python tools/blender/render_reference.py -- --reference-set media/reference

  the generalization set, one model per run, resumable (a finished image is skipped):
    for car in media/demo/car.glb ../shared/data/gltf/kenney/police/police.glb ../shared/data/gltf/ToyCar.glb \
               ../shared/data/gltf/DamagedHelmet/DamagedHelmet.gltf; do
      blender -b --factory-startup --python tools/blender/render_reference.py -- \
          --generalization-set /tmp/gen --model "$car"
    done
    every map of ../shared/data/env x the model's own materials, a glossy and a diffuse paint x
    both ground set-ups: "catcher" (the plane below, as above) and "none" (the model alone under
    the whole map, odvr render's default). The model stands on the ground: lifted so that its
    lowest point is at y = 0 (world_from_model_odvr in each image's JSON). The camera frames the model as odvr render's default
    camera does (from its front-left, a little above, 3.2 bounding radii off, 40 degrees), at
    160x90 unless --size says otherwise. A model
    with a material that Blender's importer renders as another one (NOT_RENDERED_AS_SPECIFIED:
    ToyCar's sheen) gets no images of its own materials; set.json's "left_out" says why.

  the orientation check of the environment map (writes DIR/verify_env.json):
    blender -b --factory-startup --python tools/blender/render_reference.py -- --verify-env media/reference

Conventions (odvr's, DESIGN.md and engine/sphere/equirect.h):
* World: right-handed, +Y up, metres. Blender is Z-up: odvr (x, y, z) = Blender (x, z, -y), i.e.
  Blender (X, Y, Z) = odvr (X, -Z, Y). The ground (shadow catcher) is the plane y = 0.
* Environment: the map's pixel (col, row) of W x H holds the radiance arriving from direction
  lon = pi (1 - 2 (col + 0.5) / W), lat = pi/2 - pi (row + 0.5) / H,
  d = (cos lat cos lon, sin lat, -cos lat sin lon) in odvr's frame: the centre column looks along
  +X, columns grow towards +Z (right), row 0 is the zenith (+Y). With no rotation this is exactly
  Blender's Environment Texture (equirectangular) in Blender's frame; checked by --verify-env.
  --env-yaw-deg a turns the map about +Y by a (counter-clockwise seen from above): what the map
  holds at longitude lon lights the scene from longitude lon + a. --env-rotation gives the full
  world_from_env 3x3 matrix (row-major, odvr frame) instead.
  Negative pixels (lossy EXR compression leaves some near bright sources) are clamped to 0 in the
  image, before the texture lookup interpolates.
* Camera: pinhole at --camera px,py,pz,tx,ty,tz,vfov_deg (odvr frame), image up = +Y projected,
  principal point at the image centre, square pixels; OpenCV intrinsics
  fx = fy = (H/2) / tan(vfov/2), cx = (W-1)/2, cy = (H-1)/2 (pixel centres at integers).
* Model: the glTF as Blender's importer reads it (glTF +Y up becomes Blender +Z up, so the model's
  own frame is odvr's frame unchanged), at the origin, unscaled.

Outputs for --out PREFIX:
  PREFIX.exr          RGBA, linear, premultiplied (OpenEXR's associated alpha), half float, ZIP:
                      RGB = the car's radiance over transparent film (0 off the car), alpha = car
                      coverage + shadow: alpha = m + (1 - m)(1 - lum(S)), m the coverage, S the
                      shadow ratio below (luminance clamped to [0, 1]); so "over" compositing on a
                      background B,  C + (1 - alpha) B,  shows the car and a grey shadow.
  PREFIX_mask.exr     car coverage m in [0, 1] (R = G = B), from a shader AOV that every car
                      material writes as 1 (anti-aliased like the image; equal to Cycles' own alpha
                      with the Shadow Catcher pass on, which the JSON checks).
  PREFIX_shadow.exr   Cycles' "Shadow Catcher" pass S, RGB: the ratio the catcher applies to the
                      background (light reaching the ground with the car / without it, all bounces
                      included); 1 where nothing shadows, meaningless on car pixels. The exact
                      composite is  C + (1 - m) S B.
Blender 3.4 exposes the shadow this way only: with the Shadow Catcher pass enabled, Cycles leaves
the shadow out of alpha (alpha = coverage); without the pass it puts an approximation in alpha.
With --seeds s1,s2 (two or more), each seed is rendered and the files hold their mean (the noise
estimate in the JSON compares the renders).
"""

import argparse
import json
import math
import os
import sys
import time

import bpy
import numpy as np
from mathutils import Matrix, Vector

np.bool = bool  # Blender 3.4's glTF importer still uses np.bool, removed in numpy 1.24.

# odvr (Y up) -> Blender (Z up): (x, y, z) -> (x, -z, y).
P_BLENDER_FROM_ODVR = Matrix(((1, 0, 0), (0, 0, -1), (0, 1, 0)))

MATERIALS = {
    # Principled BSDF of Blender 3.4 with the glTF metallic-roughness meaning (specular 0.5 = F0 0.04).
    "diffuse": {"roughness": 1.0, "metallic": 0.0, "specular": 0.5},
    "glossy": {"roughness": 0.25, "metallic": 0.9, "specular": 0.5},
}
DEFAULT_PAINT = (0.6, 0.6, 0.6)  # linear base colour of the override paints


def odvr_to_blender(v):
    return P_BLENDER_FROM_ODVR @ Vector(v)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="render_reference.py", description=__doc__.split("\n")[0])
    p.add_argument("--model", help="glTF model (.gltf/.glb)")
    p.add_argument("--env", help="equirect environment (EXR/HDR)")
    p.add_argument("--env-yaw-deg", type=float, default=0.0)
    p.add_argument("--env-rotation", help="world_from_env 3x3, 9 comma-separated numbers, row-major (odvr frame)")
    p.add_argument("--env-strength", type=float, default=1.0)
    p.add_argument("--camera", default="5.2,1.9,4.4,0,0.55,0,30", help="px,py,pz,tx,ty,tz,vfov_deg (odvr frame)")
    p.add_argument("--size", default=None, help="WxH (default 320x180; the generalization set's 160x90)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel per seed (default 256; the set's own)")
    p.add_argument("--seeds", default="1", help="comma-separated render seeds; files hold their mean")
    p.add_argument("--material", default="as-is", choices=["as-is", "diffuse", "glossy"])
    p.add_argument("--paint", default=",".join(str(c) for c in DEFAULT_PAINT), help="override base colour r,g,b")
    p.add_argument("--plane-size", type=float, default=60.0)
    p.add_argument("--catcher-albedo", type=float, default=0.18,
                   help="diffuse albedo of the catcher plane as the car sees it (indirect bounce)")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--out", help="output prefix (PREFIX.exr, PREFIX_mask.exr, PREFIX_shadow.exr, PREFIX.json)")
    p.add_argument("--reference-set", metavar="DIR", help="render the committed reference set into DIR")
    p.add_argument("--generalization-set", metavar="DIR",
                   help="render --model under every map of --envs-dir, every material, both grounds into DIR/<model>")
    p.add_argument("--envs-dir", default=None, help="maps of the generalization set (default ../shared/data/env)")
    p.add_argument("--verify-env", metavar="DIR", help="check the environment orientation, write DIR/verify_env.json")
    a = p.parse_args(argv)
    a.w, a.h = (int(v) for v in a.size.lower().split("x")) if a.size else (None, None)
    a.seed_list = [int(s) for s in a.seeds.split(",")]
    a.paint_rgb = tuple(float(v) for v in a.paint.split(","))
    return a


# ----------------------------------------------------------------------------------------------
# Scene


def setup_scene(threads=0):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.use_denoising = False
    # Adaptive sampling stops pixels that have converged (the film background, the ground far
    # from the car, where the catcher's ratio is exactly 1) and leaves the car and its shadow
    # the full count; it stays unbiased, and the two-seed estimate measures the noise left.
    cy.use_adaptive_sampling = True
    cy.adaptive_threshold = 0.004
    cy.max_bounces = 6
    cy.diffuse_bounces = 3
    cy.glossy_bounces = 3
    cy.transmission_bounces = 6
    cy.transparent_max_bounces = 8
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0  # no clamping
    cy.blur_glossy = 0.0
    # Caustics off (light reflected by the car onto the ground): odvr does not model them, and
    # they are the slowest paths to converge.
    cy.caustics_reflective = False
    cy.caustics_refractive = False
    cy.pixel_filter_type = "BLACKMAN_HARRIS"
    cy.filter_width = 1.5
    r = scene.render
    r.film_transparent = True
    r.use_persistent_data = True
    r.resolution_percentage = 100
    r.dither_intensity = 0.0
    r.use_compositing = True
    if threads > 0:
        r.threads_mode = "FIXED"
        r.threads = threads
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.frame_current = 1
    vl = scene.view_layers[0]
    vl.cycles.use_pass_shadow_catcher = True
    aov = vl.aovs.add()
    aov.name = "car_mask"
    aov.type = "VALUE"
    return scene


def setup_world(scene):
    world = bpy.data.worlds.new("Env")
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    mp.vector_type = "VECTOR"
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.projection = "EQUIRECTANGULAR"
    env.interpolation = "Linear"
    bg = nt.nodes.new("ShaderNodeBackground")
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
    nt.links.new(mp.outputs["Vector"], env.inputs["Vector"])
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = 1024
    return env, mp, bg


def world_from_env_odvr(yaw_deg=0.0, rotation=None):
    if rotation is not None:
        v = [float(x) for x in rotation]
        if len(v) != 9:
            raise ValueError("--env-rotation needs 9 numbers")
        R = Matrix((v[0:3], v[3:6], v[6:9]))
        if abs(R.determinant() - 1) > 1e-4 or (R @ R.transposed() - Matrix.Identity(3)).to_3x3().row[0].length > 1e-3:
            raise ValueError("--env-rotation is not a rotation")
        return R
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    return Matrix(((c, 0, s), (0, 1, 0), (-s, 0, c)))  # about +Y: +X turns towards -Z (left)


def set_env(env_node, mapping, bg, path, R_odvr, strength, scene, tmpdir):
    img = bpy.data.images.load(os.path.abspath(path), check_existing=True)
    img.colorspace_settings.name = "Linear"
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    rgb = px.reshape(-1, 4)[:, :3]
    info = {"size": [w, h], "negative_pixels": int((rgb < 0).any(axis=1).sum()), "min": float(rgb.min()),
            "max": float(rgb.max())}
    # Negative pixels are clamped in the map itself, before the texture lookup interpolates: a
    # clamp after the lookup (what this script did before) lets a bright sun's texels blend with
    # their negative neighbours, which took 9 % off sky.exr's light on the car. odvr clamps the
    # pixels the same way (image::SanitizePixels). The clamped copy goes through a file: pixels
    # written into the loaded image in memory did not render as written (4 % dark, measured).
    if info["negative_pixels"]:
        clamped = np.maximum(px.reshape(h, w, 4), 0.0)
        clamped[:, :, 3] = 1.0
        copy = os.path.join(tmpdir + "_env", "clamped_" + os.path.splitext(os.path.basename(path))[0] + ".exr")
        os.makedirs(os.path.dirname(copy), exist_ok=True)
        write_exr(scene, clamped[::-1], copy, "RGB", depth="32")
        img = bpy.data.images.load(copy, check_existing=False)
        img.colorspace_settings.name = "Linear"
    env_node.image = img
    # The map is looked up at env_from_world @ d_world; in Blender's frame that is P R^T P^T.
    Rb = P_BLENDER_FROM_ODVR @ R_odvr @ P_BLENDER_FROM_ODVR.transposed()
    lookup = Rb.transposed()
    mapping.inputs["Rotation"].default_value = lookup.to_euler("XYZ")
    bg.inputs["Strength"].default_value = strength
    return info


def import_model(path):
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))
    objs = [o for o in bpy.data.objects if o not in before]
    meshes = [o for o in objs if o.type == "MESH"]
    return meshes, [o for o in objs if o.parent is None], model_box(meshes)


def model_box(meshes):
    """The meshes' box in odvr's frame (the importer's +Y-up to +Z-up conversion makes the model
    frame odvr's frame)."""
    bpy.context.view_layer.update()
    lo = Vector((1e9, 1e9, 1e9))
    hi = -lo
    deps = bpy.context.evaluated_depsgraph_get()
    for o in meshes:
        ev = o.evaluated_get(deps)
        for v in ev.data.vertices:
            w = ev.matrix_world @ v.co
            lo = Vector(map(min, lo, w))
            hi = Vector(map(max, hi, w))
    return [[lo.x, lo.z, -hi.y], [hi.x, hi.z, -lo.y]]


def add_mask_aov(mat):
    """Every car material writes 1 to the car_mask AOV (camera hits only)."""
    if mat is None or not mat.use_nodes:
        return
    nt = mat.node_tree
    if any(n.bl_idname == "ShaderNodeOutputAOV" for n in nt.nodes):
        return
    aov = nt.nodes.new("ShaderNodeOutputAOV")
    aov.name = "car_mask"
    aov.inputs["Value"].default_value = 1.0


def make_paint(kind, rgb):
    m = bpy.data.materials.new(f"Override_{kind}")
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    p = MATERIALS[kind]
    b.inputs["Base Color"].default_value = (*rgb, 1.0)
    b.inputs["Roughness"].default_value = p["roughness"]
    b.inputs["Metallic"].default_value = p["metallic"]
    b.inputs["Specular"].default_value = p["specular"]
    add_mask_aov(m)
    return m


class MaterialSwitch:
    def __init__(self, meshes, rgb):
        self.meshes = meshes
        self.orig = {o.name: [s.material for s in o.material_slots] for o in meshes}
        for mats in self.orig.values():
            for m in mats:
                add_mask_aov(m)
        self.paints = {k: make_paint(k, rgb) for k in MATERIALS}
        for o in meshes:
            if not o.material_slots:
                o.data.materials.append(self.paints["diffuse"])  # a model without materials
                self.orig[o.name] = [None]

    def set(self, kind):
        for o in self.meshes:
            for i, s in enumerate(o.material_slots):
                s.link = "OBJECT" if kind != "as-is" else "DATA"
                if kind != "as-is":
                    s.material = self.paints[kind]
                else:
                    s.link = "DATA"


def add_catcher(scene, size, albedo):
    h = size / 2
    me = bpy.data.meshes.new("Catcher")
    me.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    ob = bpy.data.objects.new("Catcher", me)
    scene.collection.objects.link(ob)
    ob.is_shadow_catcher = True
    m = bpy.data.materials.new("CatcherGround")
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (albedo, albedo, albedo, 1)
    o = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(d.outputs["BSDF"], o.inputs["Surface"])
    me.materials.append(m)
    return ob


def set_camera(scene, cam_ob, spec, w, h):
    px, py, pz, tx, ty, tz, fov = spec
    eye = odvr_to_blender((px, py, pz))
    target = odvr_to_blender((tx, ty, tz))
    f = (target - eye).normalized()
    up = Vector((0, 0, 1))
    r = f.cross(up).normalized()
    u = r.cross(f)
    cam_ob.matrix_world = Matrix(((r.x, u.x, -f.x, eye.x), (r.y, u.y, -f.y, eye.y), (r.z, u.z, -f.z, eye.z),
                                  (0, 0, 0, 1)))
    cd = cam_ob.data
    cd.type = "PERSP"
    cd.sensor_fit = "VERTICAL"
    cd.angle_y = math.radians(fov)
    cd.clip_start = 0.01
    cd.clip_end = 1000.0
    cd.shift_x = cd.shift_y = 0.0
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    scene.camera = cam_ob
    fpx = (h / 2) / math.tan(math.radians(fov) / 2)
    return {"position": [px, py, pz], "target": [tx, ty, tz], "vfov_deg": fov, "up": [0, 1, 0],
            "intrinsics_opencv": {"fx": fpx, "fy": fpx, "cx": (w - 1) / 2, "cy": (h - 1) / 2, "width": w, "height": h},
            "blender_matrix_world": [[round(v, 9) for v in row] for row in cam_ob.matrix_world]}


def setup_compositor(scene, tmpdir):
    scene.use_nodes = True
    nt = scene.node_tree
    nt.nodes.clear()
    rl = nt.nodes.new("CompositorNodeRLayers")
    comp = nt.nodes.new("CompositorNodeComposite")
    nt.links.new(rl.outputs["Image"], comp.inputs["Image"])
    fo = nt.nodes.new("CompositorNodeOutputFile")
    fo.base_path = tmpdir
    fo.format.file_format = "OPEN_EXR"
    fo.format.color_depth = "32"
    fo.format.exr_codec = "ZIP"
    fo.format.color_mode = "RGBA"
    fo.file_slots.clear()
    for name, sock in (("rgba", "Image"), ("shadow", "Shadow Catcher"), ("mask", "car_mask")):
        fo.file_slots.new(name + "_")
        nt.links.new(rl.outputs[sock], fo.inputs[-1])
    return fo


def read_exr(path):
    img = bpy.data.images.load(path, check_existing=False)
    img.alpha_mode = "PREMUL"
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return a.reshape(h, w, 4)[::-1].copy()


def write_exr(scene, arr, path, channels, depth="16"):
    """Top-down HxWx4 (premultiplied) array to a ZIP EXR (half float, or "32") with `channels` RGB or RGBA."""
    h, w = arr.shape[:2]
    img = bpy.data.images.new("_out", w, h, alpha=True, float_buffer=True)
    img.alpha_mode = "PREMUL"
    img.pixels.foreach_set(np.ascontiguousarray(arr[::-1]).ravel())
    s = scene.render.image_settings
    s.file_format, s.color_depth, s.exr_codec, s.color_mode = "OPEN_EXR", depth, "ZIP", channels
    img.save_render(path, scene=scene)
    bpy.data.images.remove(img)


def render_once(scene, tmpdir, seed):
    scene.cycles.seed = seed
    for f in os.listdir(tmpdir):
        os.remove(os.path.join(tmpdir, f))
    t0 = time.time()
    bpy.ops.render.render(write_still=False)
    dt = time.time() - t0
    got = {}
    for name in ("rgba", "shadow", "mask"):
        got[name] = read_exr(os.path.join(tmpdir, f"{name}_0001.exr"))
    return got, dt


def noise_stats(a, b, mask, shadow_a, shadow_b):
    """Relative Monte-Carlo noise of one render, from two renders with different seeds.

    For a pixel, (a - b)/sqrt(2) has the standard deviation of one render. car_*: over pixels with
    mask > 0.99, luminance; *_rms_rel = RMS noise / mean value; *_mean_rel = mean of per-pixel
    |a - b| / (sqrt(2) (a + b)/2) (what a mean relative error picks up). shadow_*: the same on the
    shadow ratio, over ground pixels darkened by more than 5 %."""
    lum = np.array([0.2126, 0.7152, 0.0722], np.float32)
    la, lb = a[:, :, :3] @ lum, b[:, :, :3] @ lum
    car = mask > 0.99
    out = {}
    if car.any():
        d = (la - lb)[car]
        m = 0.5 * (la + lb)[car]
        out["car_pixels"] = int(car.sum())
        out["car_rms_rel"] = float(np.sqrt(np.mean(d * d) / 2) / max(1e-9, m.mean()))
        out["car_mean_rel"] = float(np.mean(np.abs(d) / np.sqrt(2) / np.maximum(m, 1e-3 * m.mean())))
    sa, sb = shadow_a[:, :, :3] @ lum, shadow_b[:, :, :3] @ lum
    ground = (mask < 0.01) & (0.5 * (sa + sb) < 0.95)
    if ground.any():
        d = (sa - sb)[ground]
        m = 0.5 * (sa + sb)[ground]
        out["shadow_pixels"] = int(ground.sum())
        out["shadow_rms_rel"] = float(np.sqrt(np.mean(d * d) / 2) / max(1e-9, m.mean()))
        out["shadow_mean_rel"] = float(np.mean(np.abs(d) / np.sqrt(2) / np.maximum(m, 1e-3)))
        dd = (1 - sa) - (1 - sb)
        out["shadow_darkening_rms_rel"] = float(np.sqrt(np.mean(dd[ground] ** 2) / 2) /
                                                max(1e-9, (1 - m).mean()))
    return out


class Renderer:
    def __init__(self, model, threads, plane_size, albedo, paint_rgb):
        self.scene = setup_scene(threads)
        self.env_node, self.mapping, self.bg = setup_world(self.scene)
        self.meshes, self.roots, self.box = import_model(model) if model else ([], [], None)
        self.lift = 0.0  # stand_on_ground's world_from_model translation along +Y (odvr frame)
        self.switch = MaterialSwitch(self.meshes, paint_rgb) if self.meshes else None
        self.catcher = add_catcher(self.scene, plane_size, albedo) if model else None
        cam = bpy.data.objects.new("RefCam", bpy.data.cameras.new("RefCam"))
        self.scene.collection.objects.link(cam)
        self.cam = cam
        self.tmpdir = os.path.join(bpy.app.tempdir or "/tmp", "odvr_ref_%d" % os.getpid())
        os.makedirs(self.tmpdir, exist_ok=True)
        setup_compositor(self.scene, self.tmpdir)

    def stand_on_ground(self):
        """Lift the model so that its lowest point touches the ground (y = 0): a model centred on
        its origin would otherwise sink through the catcher, which hides what is below it."""
        lift = -self.box[0][1]
        for o in self.roots:
            o.location.z += lift  # Blender +Z is odvr +Y
        self.lift += lift
        self.box = model_box(self.meshes)

    def world_from_model(self):
        """world_from_model (odvr frame, row-major 4x4) of the model as placed."""
        return [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, self.lift], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]

    def render(self, out_prefix, env, R_odvr, strength, camera, w, h, spp, seeds, material, ground="catcher"):
        if self.catcher:
            self.catcher.hide_render = ground == "none"
        env_info = set_env(self.env_node, self.mapping, self.bg, env, R_odvr, strength, self.scene, self.tmpdir)
        cam_info = set_camera(self.scene, self.cam, camera, w, h)
        if self.switch:
            self.switch.set(material)
        self.scene.cycles.samples = spp
        self.scene.cycles.adaptive_min_samples = max(16, spp // 4)
        runs, times = [], []
        for s in seeds:
            got, dt = render_once(self.scene, self.tmpdir, s)
            runs.append(got)
            times.append(dt)
        mean = {k: sum(r[k] for r in runs) / len(runs) for k in runs[0]}
        os.makedirs(os.path.dirname(os.path.abspath(out_prefix)), exist_ok=True)
        # With the Shadow Catcher pass on, Cycles keeps alpha = car coverage and puts the shadow in
        # the pass; fold its luminance into alpha so that "C + (1 - alpha) B" shows the shadow.
        lum = np.array([0.2126, 0.7152, 0.0722], np.float32)
        s_lum = np.clip(mean["shadow"][:, :, :3] @ lum, 0.0, 1.0)
        rgba = mean["rgba"].copy()
        coverage = rgba[:, :, 3].copy()
        rgba[:, :, 3] = coverage + (1.0 - coverage) * (1.0 - s_lum)
        write_exr(self.scene, rgba, out_prefix + ".exr", "RGBA")
        m = mean["mask"].copy()
        m[:, :, 1] = m[:, :, 2] = m[:, :, 0]
        m[:, :, 3] = 1.0
        write_exr(self.scene, m, out_prefix + "_mask.exr", "RGB")
        sh = mean["shadow"].copy()
        sh[:, :, 3] = 1.0
        write_exr(self.scene, sh, out_prefix + "_shadow.exr", "RGB")
        info = {"files": {"rgba": os.path.basename(out_prefix) + ".exr",
                          "mask": os.path.basename(out_prefix) + "_mask.exr",
                          "shadow": os.path.basename(out_prefix) + "_shadow.exr"},
                "env": env, "env_info": env_info, "env_world_from_env_odvr": [list(r) for r in R_odvr],
                "env_strength": strength, "camera": cam_info, "size": [w, h], "spp_per_seed": spp,
                "seeds": seeds, "spp_total": spp * len(seeds), "render_seconds": [round(t, 2) for t in times],
                "material": material, "ground": ground,
                "mask_coverage": float(mean["mask"][:, :, 0].mean()),
                "cycles_alpha_mean": float(coverage.mean()),
                "mask_vs_cycles_alpha_max_abs_diff": float(np.abs(mean["mask"][:, :, 0] - coverage).max()),
                "alpha_mean": float(rgba[:, :, 3].mean()),
                "rgb_max_off_car": float(mean["rgba"][:, :, :3][coverage < 1e-4].max(initial=0.0)),
                "shadow_min": float(s_lum.min())}
        if material != "as-is":
            info["material_params"] = dict(MATERIALS[material], base_color=list(self.switch.paints[material].node_tree
                                                                                 .nodes["Principled BSDF"]
                                                                                 .inputs["Base Color"].default_value)[:3])
        if len(runs) >= 2:
            ns = noise_stats(runs[0]["rgba"], runs[1]["rgba"], mean["mask"][:, :, 0], runs[0]["shadow"],
                             runs[1]["shadow"])
            ns["note"] = ("relative noise of ONE render of spp_per_seed samples; the committed mean of n seeds "
                          "has about 1/sqrt(n) of it")
            ns["mean_of_seeds_car_mean_rel"] = ns.get("car_mean_rel", 0) / math.sqrt(len(runs))
            ns["mean_of_seeds_shadow_mean_rel"] = ns.get("shadow_mean_rel", 0) / math.sqrt(len(runs))
            info["noise"] = ns
        return info


def write_json(path, obj):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(obj, f, indent=1)
        f.write("\n")
    os.replace(tmp, path)


# ----------------------------------------------------------------------------------------------
# Orientation check: bright spots at known odvr directions, seen through the odvr camera.


def verify_env(out_dir, threads):
    """Writes maps with two bright spots (a strong one and a weaker one 12 deg to its right, so a
    mirror image would be caught) at directions given by odvr's equirect formula, renders them
    with nothing in the scene through a pinhole aimed by odvr's camera convention, and compares
    the detected spots with their projections. Done for no rotation, a yaw, and a general rotation."""
    os.makedirs(out_dir, exist_ok=True)
    r = Renderer(None, threads, 0, 0, DEFAULT_PAINT)
    scene = r.scene
    scene.render.film_transparent = False
    W, H = 512, 256
    spot_dir = r.tmpdir + "_maps"  # render_once empties r.tmpdir
    os.makedirs(spot_dir, exist_ok=True)

    def dir_of(lon, lat):
        return Vector((math.cos(lat) * math.cos(lon), math.sin(lat), -math.cos(lat) * math.sin(lon)))

    cases = [("identity", 0.0, None, (0.6, 0.25)), ("yaw_90", 90.0, None, (-2.2, -0.3)),
             ("general", 0.0, None, (2.5, 0.7))]
    Rg = (Matrix.Rotation(0.7, 3, "Y") @ Matrix.Rotation(-0.4, 3, "X") @ Matrix.Rotation(0.3, 3, "Z"))
    results = []
    for name, yaw, _, (lon, lat) in cases:
        # Map with the spots at (lon, lat) and 12 deg to the right of it (towards +Z at the horizon).
        img = np.zeros((H, W, 4), np.float32)
        img[:, :, 3] = 1
        spots = [(dir_of(lon, lat), 200.0), (dir_of(lon - math.radians(12) / max(0.2, math.cos(lat)), lat), 60.0)]
        rows = (np.arange(H) + 0.5) / H
        cols = (np.arange(W) + 0.5) / W
        LAT = (math.pi / 2 - math.pi * rows)[:, None]
        LON = (math.pi * (1 - 2 * cols))[None, :]
        D = np.stack([np.cos(LAT) * np.cos(LON), np.sin(LAT) * np.ones_like(LON), -np.cos(LAT) * np.sin(LON)], axis=2)
        for d, val in spots:
            ang = np.arccos(np.clip(D @ np.array(list(d)), -1, 1))
            img[:, :, :3] += (val * np.exp(-(ang / math.radians(1.2)) ** 2))[:, :, None]
        path = os.path.join(spot_dir, f"spots_{name}.exr")
        write_exr(scene, img, path, "RGB")
        R = Rg if name == "general" else world_from_env_odvr(yaw)
        world_dirs = [R @ d for d, _ in spots]
        mid = (world_dirs[0] + world_dirs[1]).normalized()
        cam = (0.0, 0.0, 0.0, mid.x, mid.y, mid.z, 40.0)
        w, h = 320, 240
        info = r.render(os.path.join(r.tmpdir, "v_" + name), path, R, 1.0, cam, w, h, 16, [1], "as-is")
        bpy.data.images.remove(bpy.data.images[os.path.basename(path)])
        rgba = read_exr(os.path.join(r.tmpdir, "v_" + name + ".exr"))
        lum = rgba[:, :, :3].mean(axis=2)
        # Project the expected directions with the OpenCV pinhole of the odvr camera.
        f = mid
        right = f.cross(Vector((0, 1, 0))).normalized()
        down = f.cross(right)
        fpx = (h / 2) / math.tan(math.radians(40) / 2)
        errs = []
        found = []
        for (d, val), wd in zip(spots, world_dirs):
            x, y, z = wd.dot(right), wd.dot(down), wd.dot(f)
            u, v = fpx * x / z + (w - 1) / 2, fpx * y / z + (h - 1) / 2
            rr = 10
            y0, y1, x0, x1 = int(max(0, v - rr)), int(min(h, v + rr + 1)), int(max(0, u - rr)), int(min(w, u + rr + 1))
            patch = lum[y0:y1, x0:x1]
            # Spot present where predicted, and the brighter one is the strong spot.
            if patch.size and patch.max() > 0.2 * val:
                yy, xx = np.mgrid[y0:y1, x0:x1]
                cu, cv = float((xx * patch).sum() / patch.sum()), float((yy * patch).sum() / patch.sum())
                errs.append(math.hypot(cu - u, cv - v))
                found.append({"predicted_px": [round(u, 3), round(v, 3)], "found_px": [round(cu, 3), round(cv, 3)],
                              "peak": float(patch.max())})
            else:
                found.append({"predicted_px": [round(u, 3), round(v, 3)], "found_px": None})
        results.append({"case": name, "world_from_env": [[round(x, 6) for x in row] for row in R],
                        "map_lon_lat_deg": [math.degrees(lon), math.degrees(lat)], "spots": found,
                        "max_err_px": round(max(errs), 4) if len(errs) == 2 else None,
                        "image_peak_total": float(lum.max())})
    ok = all(c["max_err_px"] is not None and c["max_err_px"] < 1.0 for c in results)
    js = {"what": "bright spots written at odvr equirect directions, rendered by Cycles through the odvr "
                  "camera convention; predicted vs found pixel (intensity centroid)",
          "cases": results, "pass": ok}
    write_json(os.path.join(out_dir, "verify_env.json"), js)
    print("VERIFY_ENV", json.dumps(js))
    return ok


# ----------------------------------------------------------------------------------------------
# The committed set

REFERENCE_SET = {
    "model": "media/demo/car.glb",
    "envs": [("sky", "../shared/data/env/sky.exr"), ("sunset", "../shared/data/env/sunset.exr"),
             ("studio", "../shared/data/env/studio.exr")],
    "materials": ["diffuse", "glossy"],
    "camera": (5.2, 1.9, 4.4, 0.0, 0.55, 0.0, 30.0),
    "size": (320, 180),
    "spp": 128,
    "seeds": [1, 2],
    "env_yaw_deg": 0.0,
}


def reference_set(out_dir, threads, spp=None):
    repo = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    rs = dict(REFERENCE_SET)
    if spp:
        rs["spp"] = spp
    model = os.path.join(repo, rs["model"])
    r = Renderer(model, threads, 60.0, 0.18, DEFAULT_PAINT)
    entries = []
    R = world_from_env_odvr(rs["env_yaw_deg"])
    t0 = time.time()
    for env_name, env_rel in rs["envs"]:
        env = os.path.normpath(os.path.join(repo, env_rel))
        for mat in rs["materials"]:
            name = f"{env_name}_{mat}"
            info = r.render(os.path.join(out_dir, name), env, R, 1.0, rs["camera"], *rs["size"], rs["spp"],
                            rs["seeds"], mat)
            info["env"] = env_rel
            info["name"] = name
            entries.append(info)
            print(f"{name}: {sum(info['render_seconds']):.1f} s, noise {json.dumps(info.get('noise', {}))}", flush=True)
    js = {"what": "Cycles references for odvr's renderer: the model on a shadow catcher, lit only by the environment",
          "command": "blender -b --factory-startup --python tools/blender/render_reference.py -- --reference-set "
                     + os.path.relpath(out_dir, repo),
          "blender": bpy.app.version_string, "model": rs["model"], "model_box_odvr": r.box,
          "catcher": {"plane": "y = 0, 60 x 60 m centred at the origin, Cycles shadow catcher",
                      "albedo_seen_by_the_car": 0.18},
          "cycles": {"device": "CPU", "adaptive_sampling": "threshold 0.004, min samples spp/4",
                     "denoising": False, "max_bounces": 6, "diffuse_bounces": 3, "glossy_bounces": 3,
                     "clamp": "none", "filter_glossy": 0, "caustics": False,
                     "pixel_filter": "Blackman-Harris 1.5 px", "film": "transparent",
                     "env_interpolation": "Linear", "env_importance_map": 1024},
          "conventions": __doc__.split("Conventions (odvr's, DESIGN.md and engine/sphere/equirect.h):")[1]
                                .split("Outputs for")[0].strip(),
          "outputs": __doc__.split("Outputs for --out PREFIX:")[1].strip(),
          "total_seconds": round(time.time() - t0, 1),
          "images": entries}
    write_json(os.path.join(out_dir, "references.json"), js)

def default_camera(box_odvr, vfov_deg=40.0):
    """odvr render's default camera (app/cli/run_render.cpp, DefaultCamera): the model's bounding box
    seen from its front-left, a little above, 3.2 bounding radii from its centre."""
    lo, hi = np.array(box_odvr[0]), np.array(box_odvr[1])
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
    d = np.array([0.75, 0.35, 0.9])
    eye = centre + 3.2 * radius * d / np.linalg.norm(d)
    return [*map(float, eye), *map(float, centre), vfov_deg]


# glTF material extensions that Blender 3.4's importer turns into a different material, so that a
# Cycles render of the model's own materials is not a reference for a renderer that follows the
# glTF specification. KHR_materials_sheen: the importer adds a Velvet BSDF (Ashikhmin's lobe, its
# colour the sheen colour) on top of the whole base layer, where the specification layers a
# Charlie lobe over the base scaled down by the sheen's albedo; ToyCar's red sheen on grey cloth
# renders saturated red in Cycles and a dim red rim per the specification.
NOT_RENDERED_AS_SPECIFIED = {
    "KHR_materials_sheen": "Blender 3.4's importer adds a Velvet BSDF on top of the base layer instead of the "
                           "specification's Charlie sheen over a base scaled by the sheen's albedo",
}


def gltf_json(path):
    """The glTF's JSON: the file itself (.gltf) or a .glb's first chunk."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"glTF":
        return json.loads(data.decode("utf-8"))
    length = int.from_bytes(data[12:16], "little")
    return json.loads(data[20:20 + length].decode("utf-8"))


def materials_not_rendered_as_specified(path):
    """{material name: why} for the model's materials whose extensions Cycles cannot render as the
    glTF specification defines them (NOT_RENDERED_AS_SPECIFIED)."""
    out = {}
    for i, m in enumerate(gltf_json(path).get("materials", [])):
        for ext in m.get("extensions", {}):
            if ext in NOT_RENDERED_AS_SPECIFIED:
                out[m.get("name", f"material {i}")] = f"{ext}: {NOT_RENDERED_AS_SPECIFIED[ext]}"
    return out


# 160x90: the size docs/benchmarks/render_set.md was measured at; the four models' 396 images
# take about 35 minutes on two cores.
GENERALIZATION = {"size": (160, 90), "spp": 256, "seeds": [1, 2], "materials": ["as-is", "glossy", "diffuse"],
                  "grounds": ["catcher", "none"], "catcher_albedo": 0.18}


def generalization_set(out_root, model, envs_dir, threads, spp=None, size=None):
    """One model under every map, material and ground; DIR/<model>/set.json lists what is done.
    An image whose JSON exists is kept, so an interrupted run goes on where it stopped."""
    g = dict(GENERALIZATION, spp=spp or GENERALIZATION["spp"], size=tuple(size or GENERALIZATION["size"]))
    # A model whose own materials Cycles would render as another material has no "as-is"
    # reference: the paints still measure its geometry, and set.json says what was left out.
    left_out = {}
    unfaithful = materials_not_rendered_as_specified(model)
    if unfaithful:
        g["materials"] = [m for m in g["materials"] if m != "as-is"]
        left_out["as-is"] = "; ".join(f"{name}: {why}" for name, why in sorted(unfaithful.items()))
        print(f"render_reference.py: {model}: its own materials left out ({left_out['as-is']})", flush=True)
    model_name = os.path.splitext(os.path.basename(model))[0]
    out_dir = os.path.join(out_root, model_name)
    # A model inside the repository is named relative to it, so that a committed set is found
    # from any clone; another keeps its absolute path.
    repo = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    model_ref = os.path.abspath(model)
    if os.path.commonpath([model_ref, repo]) == repo:
        model_ref = os.path.relpath(model_ref, repo)
    os.makedirs(out_dir, exist_ok=True)
    envs = sorted(f for f in os.listdir(envs_dir) if f.endswith((".exr", ".hdr")))
    r = Renderer(model, threads, 60.0, g["catcher_albedo"], DEFAULT_PAINT)
    r.stand_on_ground()
    camera = default_camera(r.box)
    R = world_from_env_odvr(0.0)
    entries, t0 = [], time.time()
    for env_file in envs:
        for mat in g["materials"]:
            for ground in g["grounds"]:
                name = f"{os.path.splitext(env_file)[0]}_{mat}_{ground}"
                prefix = os.path.join(out_dir, name)
                if os.path.exists(prefix + ".json"):
                    with open(prefix + ".json") as f:
                        entries.append(json.load(f))
                    continue
                info = r.render(prefix, os.path.join(envs_dir, env_file), R, 1.0, camera, *g["size"], g["spp"],
                                g["seeds"], mat, ground)
                info.update(name=name, env=env_file, model=model_ref, model_box_odvr=r.box,
                            world_from_model_odvr=r.world_from_model())
                write_json(prefix + ".json", info)
                entries.append(info)
                print(f"{model_name}/{name}: {sum(info['render_seconds']):.1f} s, noise "
                      f"{info.get('noise', {}).get('mean_of_seeds_car_mean_rel', float('nan')):.4f}", flush=True)
    write_json(os.path.join(out_dir, "set.json"),
               {"what": "Cycles references of one model under every map, material and ground",
                "model": model_ref, "model_box_odvr": r.box, "world_from_model_odvr": r.world_from_model(),
                "camera": camera, "settings": g,
                "catcher": {"plane": "y = 0, 60 x 60 m centred at the origin, Cycles shadow catcher",
                            "albedo_seen_by_the_car": g["catcher_albedo"]},
                "seconds_this_run": round(time.time() - t0, 1), "images": [e["name"] for e in entries],
                "left_out": left_out})



def main():
    a = parse_args()
    if a.verify_env:
        ok = verify_env(a.verify_env, a.threads)
        sys.exit(0 if ok else 1)
    if a.reference_set:
        reference_set(a.reference_set, a.threads, a.spp)
        return
    if a.generalization_set:
        if not a.model:
            print("render_reference.py: --generalization-set needs --model")
            sys.exit(2)
        repo = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
        envs_dir = a.envs_dir or os.path.normpath(os.path.join(repo, "..", "shared", "data", "env"))
        generalization_set(a.generalization_set, a.model, envs_dir, a.threads, a.spp, (a.w, a.h) if a.size else None)
        return
    if not (a.model and a.env and a.out):
        print("render_reference.py: --model, --env and --out are needed (or --reference-set / --verify-env)")
        sys.exit(2)
    cam = [float(v) for v in a.camera.split(",")]
    if len(cam) != 7:
        print("render_reference.py: --camera needs px,py,pz,tx,ty,tz,vfov_deg")
        sys.exit(2)
    r = Renderer(a.model, a.threads, a.plane_size, a.catcher_albedo, a.paint_rgb)
    R = world_from_env_odvr(a.env_yaw_deg, a.env_rotation.split(",") if a.env_rotation else None)
    info = r.render(a.out, a.env, R, a.env_strength, cam, a.w or 320, a.h or 180, a.spp or 256, a.seed_list,
                    a.material)
    info["model"] = a.model
    info["model_box_odvr"] = r.box
    info["catcher"] = {"plane_size_m": a.plane_size, "albedo": a.catcher_albedo}
    write_json(a.out + ".json", info)
    print(json.dumps({k: info[k] for k in ("render_seconds", "mask_coverage", "alpha_mean")}))
    if "noise" in info:
        print("noise", json.dumps(info["noise"]))


if __name__ == "__main__":
    try:
        main()
    except SystemExit:
        raise
    except Exception:
        import traceback
        traceback.print_exc()
        sys.exit(1)
