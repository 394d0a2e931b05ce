"""Cycles variants of the committed references, to attribute odvr's error against them.

Renders an image of media/reference/ again with one physical term changed and prints, per
variant, `bias` (ΣY/ΣY_ref) and `mean_rel` (mean |Y − Y_ref| / max(Y_ref, 0.05 mean Y_ref)) over
car pixels (coverage > 0.99), Y the luminance — the measures of `odvr bench render`:

  blender -b --factory-startup --python tools/blender/reference_variants.py -- \
      sky_diffuse,studio_glossy base,direct,emu_direct,noselfbounce 64 /tmp/variants

Variants (joined with '_' they combine, e.g. emu_direct):
  base          the reference's own scene (a fresh seed: its mean_rel is the noise of both)
  direct        max bounces 0: light straight from the map, the catcher only occluding
  b1            max bounces 1
  lambert       the diffuse paint as a Lambertian BSDF instead of the Principled one
  nocatcher     no catcher: the car lit by the map's own lower half
  emu           no catcher, the map's lower half replaced by 0.18 E / π (E from the upper half):
                what odvr's bench lights the car with below the horizon
  noselfbounce  the car invisible to its own diffuse and glossy rays (no interreflections: they see
                what is behind the car; the catcher's bounce, shadowed by the car, stays)
  blackself     the car black to every ray but the camera's (its own reflections and bounce are
                occlusion, as odvr's cones make them; the catcher's bounce stays): odvr's model
  diffuseself   the car diffuse (base colour × (1 − metallic), Lambert) to every ray but the camera's:
                its light on itself without the specular part, what a radiance per voxel would carry
  noshadowcar   the car casts no shadow (on itself or the catcher)
Writes OUT/<image>_<variant>.exr (and masks) and OUT/variants.json.
"""
import importlib.util
import json
import os
import sys

import bpy
import numpy as np

np.bool = bool  # Blender 3.4's glTF importer still uses np.bool

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
_spec = importlib.util.spec_from_file_location("render_reference", os.path.join(REPO, "tools/blender/render_reference.py"))
rr = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rr)
LUM = np.array([0.2126, 0.7152, 0.0722], np.float32)


def scores(img, ref, mask):
    ya, yb = img[:, :, :3] @ LUM, ref[:, :, :3] @ LUM
    car = mask > 0.99
    m = yb[car].mean()
    return {"bias": float(ya[car].sum() / yb[car].sum()),
            "mean_rel": float(np.mean(np.abs(ya[car] - yb[car]) / np.maximum(yb[car], 0.05 * m)))}


def ground_stand_in(r, env, out_dir):
    """The map with its lower half = 0.18 E / π (app/cli/bench_render.cpp's ReplaceLowerHemisphereByGround)."""
    out = os.path.join(out_dir, "ground_" + os.path.basename(env))
    img = bpy.data.images.load(env, check_existing=False)
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    a = np.maximum(a.reshape(h, w, 4)[::-1], 0.0)
    a[:, :, 3] = 1.0
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    d_omega = (2 * np.pi / w) * (np.pi / h) * np.cos(lat)
    up = lat > 0
    e = (a[up, :, :3] * (np.sin(lat[up]) * d_omega[up])[:, None, None]).sum(axis=(0, 1))
    a[h // 2:, :, :3] = 0.18 * e / np.pi
    rr.write_exr(r.scene, a, out, "RGB", depth="32")
    return out


def camera_only(paint):
    """The paint to camera rays, black to all others (Light Path's Is Camera Ray)."""
    nt = paint.node_tree
    if "CameraOnly" in nt.nodes:
        return nt.nodes["CameraOnly"]
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.name = "CameraOnly"
    black = nt.nodes.new("ShaderNodeBsdfDiffuse")
    black.name = "CameraOnlyBlack"
    black.inputs["Color"].default_value = (0, 0, 0, 1)
    path = nt.nodes.new("ShaderNodeLightPath")
    nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    nt.links.new(black.outputs["BSDF"], mix.inputs[1])
    return mix


def configure(r, v):
    cy = r.scene.cycles
    cy.max_bounces = 0 if "direct" in v else (1 if "b1" in v else 6)
    r.catcher.hide_render = "nocatcher" in v or "emu" in v
    for o in r.meshes:
        o.visible_shadow = "noshadowcar" not in v
        o.visible_diffuse = o.visible_glossy = "noselfbounce" not in v
    for kind, paint in r.switch.paints.items():
        nt = paint.node_tree
        out, pb = nt.nodes["Material Output"], nt.nodes["Principled BSDF"]
        for link in list(out.inputs["Surface"].links):
            nt.links.remove(link)
        surface = pb.outputs["BSDF"]
        if "lambert" in v and kind == "diffuse":
            d = nt.nodes.get("Lambert") or nt.nodes.new("ShaderNodeBsdfDiffuse")
            d.name = "Lambert"
            d.inputs["Color"].default_value = pb.inputs["Base Color"].default_value
            d.inputs["Roughness"].default_value = 0.0
            surface = d.outputs["BSDF"]
        if "blackself" in v or "diffuseself" in v:
            mix = camera_only(paint)
            for link in list(mix.inputs[2].links):
                nt.links.remove(link)
            nt.links.new(surface, mix.inputs[2])
            others = nt.nodes["CameraOnlyBlack"]
            if "diffuseself" in v:
                base = pb.inputs["Base Color"].default_value
                metallic = pb.inputs["Metallic"].default_value
                others.inputs["Color"].default_value = (*(c * (1 - metallic) for c in base[:3]), 1)
            else:
                others.inputs["Color"].default_value = (0, 0, 0, 1)
            surface = mix.outputs["Shader"]
        nt.links.new(surface, out.inputs["Surface"])


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    names, variants = argv[0].split(","), argv[1].split(",")
    spp = int(argv[2]) if len(argv) > 2 else 64
    out_dir = argv[3] if len(argv) > 3 else "/tmp/odvr_variants"
    os.makedirs(out_dir, exist_ok=True)
    ref_dir = os.path.join(REPO, "media/reference")
    refs = json.load(open(os.path.join(ref_dir, "references.json")))
    r = rr.Renderer(os.path.join(REPO, refs["model"]), 0, 60.0, refs["catcher"]["albedo_seen_by_the_car"],
                    rr.DEFAULT_PAINT)
    results = {}
    for name in names:
        im = next(i for i in refs["images"] if i["name"] == name)
        env = os.path.normpath(os.path.join(REPO, im["env"]))
        ref = rr.read_exr(os.path.join(ref_dir, im["files"]["rgba"]))
        mask = rr.read_exr(os.path.join(ref_dir, im["files"]["mask"]))[:, :, 0]
        c = im["camera"]
        cam = (*c["position"], *c["target"], c["vfov_deg"])
        for v in variants:
            configure(r, v)
            e = ground_stand_in(r, env, out_dir) if "emu" in v else env
            prefix = os.path.join(out_dir, f"{name}_{v}")
            r.render(prefix, e, rr.world_from_env_odvr(0), 1.0, cam, *im["size"], spp, [7], im["material"])
            results[f"{name}:{v}"] = scores(rr.read_exr(prefix + ".exr"), ref, mask)
            print("VARIANT", name, v, json.dumps(results[f"{name}:{v}"]), flush=True)
    rr.write_json(os.path.join(out_dir, "variants.json"), results)


if __name__ == "__main__":
    main()
