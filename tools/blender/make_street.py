"""odvr's demo street: a procedural street driven by a six-fisheye rig, rendered with Cycles.

Run headless (Debian's Blender 3.4.1, CPU Cycles; see media/README.md for the exact command):

    blender -b --factory-startup --python tools/blender/make_street.py -- --out media/demo \
        --seed 7 --frames 24 --verify

Writes, per frame, the six fisheye images (rig/camC/NNNNNN.jpg), the ground-truth panorama from the
rig centre (pano/NNNNNN.png, and pano_hdr/NNNNNN.exr for a few frames), a 1024x512 H.264 clip of
the panoramas (street.mp4), the trajectory (trajectory_gt.json/.tum), the rig (rig.json), the
scene description (scene.json), a procedural car (car.glb) and checks.json. The file layout and
every convention are those of ../shared/data/street_a (README there), so the same readers apply.

Everything random comes from --seed; images are reproducible (fixed render seeds per image).
"""

import argparse
import bmesh
import json
import math
import os
import random
import shutil
import subprocess
import sys
import time

import bpy
import numpy as np
from mathutils import Matrix, Vector

np.bool = bool  # Blender 3.4's glTF add-on still uses np.bool, removed in numpy 1.24.

# ----------------------------------------------------------------------------------------------
# Arguments


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="make_street.py", description=__doc__.split("\n")[0])
    p.add_argument("--out", required=True, help="output directory (created)")
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--frames", type=int, default=24)
    p.add_argument("--fps", type=float, default=25.0)
    p.add_argument("--speed", type=float, default=9.0, help="rig speed in m/s")
    p.add_argument("--rig-size", default="300x400", help="fisheye image WxH (portrait, 3:4)")
    p.add_argument("--pano-render-size", default="1024x512", help="rendered panorama (video) WxH")
    p.add_argument("--pano-size", default="512x256",
                   help="committed panorama WxH (2x2 area mean of the rendered one, or equal to it)")
    p.add_argument("--spp", type=int, default=8, help="samples per pixel, rig images")
    p.add_argument("--pano-spp", type=int, default=6, help="samples per pixel, rendered panoramas")
    p.add_argument("--adaptive-threshold", type=float, default=0.02,
                   help="Cycles' adaptive sampling noise threshold (lower: more samples where noisy)")
    p.add_argument("--clamp-indirect", type=float, default=3.0,
                   help="Cycles' indirect sample clamp, in the scene's linear radiance (a sunlit grey road is ~0.2)")
    p.add_argument("--rig-frames", type=int, default=-1,
                   help="render the six fisheyes and the committed pano/ for the first N frames only "
                        "(default: every frame; 0: a panorama clip alone)")
    p.add_argument("--denoise", action="store_true",
                   help="filter the Monte-Carlo speckle out of the panoramas' diffuse light (see 'Denoising the panoramas')")
    p.add_argument("--video-crf", type=int, default=26, help="x264 constant rate factor of street.mp4")
    p.add_argument("--resume", action="store_true",
                   help="keep OUT/_work and skip the frames already rendered there (an interrupted render "
                        "goes on where it stopped; the scene is rebuilt identically from --seed)")
    p.add_argument("--frame-range", default="",
                   help="START:END: render only frames START..END-1 into OUT/_work and stop (no video, no checks), "
                        "so that several processes share one render; copy their _work/pano_render and "
                        "frames_done.json entries into one OUT and finish there with --resume")
    p.add_argument("--diffuse-bounces", type=int, default=0,
                   help="indirect diffuse bounces (0: shadows lit by the sky only; each bounce ~doubles the time)")
    p.add_argument("--hdr-frames", default="", help="comma-separated frames with an EXR (default: 3 spread)")
    p.add_argument("--jpeg-quality", type=int, default=75)
    p.add_argument("--threads", type=int, default=0, help="Cycles threads (0 = all cores)")
    p.add_argument("--no-video", action="store_true", help="skip street.mp4 (ffmpeg)")
    p.add_argument("--car-only", action="store_true", help="only build and export car.glb")
    p.add_argument("--verify", action="store_true",
                   help="also check the fisheye and equirect conventions with emissive markers")
    p.add_argument("--keep-work", action="store_true", help="keep OUT/_work (rendered 1024x512 frames)")
    a = p.parse_args(argv)

    def size(s):
        w, h = s.lower().split("x")
        return int(w), int(h)

    a.rig_w, a.rig_h = size(a.rig_size)
    a.pr_w, a.pr_h = size(a.pano_render_size)
    a.p_w, a.p_h = size(a.pano_size)
    if (a.pr_w, a.pr_h) != (a.p_w, a.p_h) and (a.pr_w, a.pr_h) != (2 * a.p_w, 2 * a.p_h):
        p.error("--pano-size must equal --pano-render-size or be half of it")
    a.only = range(a.frames)
    if a.frame_range:
        try:
            start, end = (int(v) for v in a.frame_range.split(":"))
        except ValueError:
            start, end = 0, 0
        if not 0 <= start < end <= a.frames:
            p.error(f"--frame-range {a.frame_range}: expected START:END with 0 <= START < END <= --frames")
        a.only = range(start, end)
    if a.rig_frames < 0 or a.rig_frames > a.frames:
        a.rig_frames = a.frames
    if a.hdr_frames:
        a.hdr = sorted({int(x) for x in a.hdr_frames.split(",") if 0 <= int(x) < a.frames})
    else:
        n = a.rig_frames if a.rig_frames > 0 else a.frames
        a.hdr = sorted({0, n // 2}) if n > 1 else [0]
    return a


# ----------------------------------------------------------------------------------------------
# Small helpers


def srgb_encode(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_decode(x):
    return np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4))


def rounded(v, nd=9):
    if isinstance(v, (list, tuple)):
        return [rounded(x, nd) for x in v]
    if isinstance(v, Matrix):
        return [rounded(list(r), nd) for r in v]
    if isinstance(v, float):
        return round(v, nd)
    return v


def write_json(path, obj):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(obj, f, indent=1)
        f.write("\n")
    os.replace(tmp, path)


def periodic_noise(rng, h, w, beta=2.0, kmin=0.0):
    """Zero-mean, unit-variance 1/f^beta noise; periodic, so it tiles."""
    f = np.fft.fft2(rng.standard_normal((h, w)))
    ky = np.fft.fftfreq(h)[:, None]
    kx = np.fft.fftfreq(w)[None, :]
    k = np.sqrt(kx * kx + ky * ky)
    k[0, 0] = 1.0
    f *= np.power(np.maximum(k, kmin if kmin > 0 else 1e-9), -beta / 2)
    f[0, 0] = 0.0
    n = np.real(np.fft.ifft2(f))
    return n / (n.std() + 1e-12)


TEX_DIR = None  # set in main(): textures go through PNG files (Cycles and the glTF exporter read them)


def make_image(name, arr, non_color=False):
    """Image from a top-down HxWx{1,3} array of sRGB-encoded (or raw) values in [0, 1], written as
    an 8-bit PNG and loaded back (a generated image's pixels do not survive packing)."""
    arr = np.asarray(arr, dtype=np.float32)
    if arr.ndim == 2:
        arr = np.repeat(arr[:, :, None], 3, axis=2)
    h, w = arr.shape[:2]
    tmp = bpy.data.images.new("_tex", w, h, alpha=False, float_buffer=False)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[:, :, :3] = np.clip(arr[::-1], 0, 1)
    tmp.pixels.foreach_set(rgba.ravel())
    path = os.path.join(TEX_DIR, name + ".png")
    tmp.filepath_raw = path
    tmp.file_format = "PNG"
    tmp.save()
    bpy.data.images.remove(tmp)
    img = bpy.data.images.load(path, check_existing=False)
    img.name = name
    img.colorspace_settings.name = "Non-Color" if non_color else "sRGB"
    return img


def link(nt, a, b):
    nt.links.new(a, b)


def principled(name, color=(0.8, 0.8, 0.8), rough=0.5, metal=0.0, spec=0.5, emission=None, estrength=1.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = (*color, 1.0)
    b.inputs["Roughness"].default_value = rough
    b.inputs["Metallic"].default_value = metal
    b.inputs["Specular"].default_value = spec
    if emission is not None:
        b.inputs["Emission"].default_value = (*emission, 1.0)
        b.inputs["Emission Strength"].default_value = estrength
    return m


def textured(name, color_img, rough=0.8, rough_img=None, rough_lo=0.1, bump_img=None, bump=0.02,
             coord="UV", scale=1.0, noise_mod=0.0, noise_scale=0.2, spec=0.5):
    """Principled material with an image base colour, optional roughness mask and bump map.

    noise_mod > 0 multiplies the colour by a large-scale object-space noise so tiled textures
    do not repeat exactly (features for tracking stay unique)."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    b = nt.nodes["Principled BSDF"]
    b.inputs["Specular"].default_value = spec
    tc = nt.nodes.new("ShaderNodeTexCoord")
    vec = tc.outputs["UV"] if coord == "UV" else tc.outputs["Object"]
    if scale != 1.0:
        mp = nt.nodes.new("ShaderNodeMapping")
        mp.inputs["Scale"].default_value = (scale, scale, scale)
        link(nt, vec, mp.inputs["Vector"])
        vec = mp.outputs["Vector"]
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = color_img
    tex.interpolation = "Linear"
    link(nt, vec, tex.inputs["Vector"])
    col = tex.outputs["Color"]
    if noise_mod > 0:
        nz = nt.nodes.new("ShaderNodeTexNoise")
        nz.inputs["Scale"].default_value = noise_scale
        nz.inputs["Detail"].default_value = 3.0
        link(nt, tc.outputs["Object"], nz.inputs["Vector"])
        mr = nt.nodes.new("ShaderNodeMapRange")
        mr.inputs["To Min"].default_value = 1.0 - noise_mod
        mr.inputs["To Max"].default_value = 1.0 + noise_mod
        mr.inputs["From Min"].default_value = 0.3
        mr.inputs["From Max"].default_value = 0.7
        link(nt, nz.outputs["Fac"], mr.inputs["Value"])
        mix = nt.nodes.new("ShaderNodeMixRGB")
        mix.blend_type = "MULTIPLY"
        mix.inputs["Fac"].default_value = 1.0
        link(nt, col, mix.inputs["Color1"])
        link(nt, mr.outputs["Result"], mix.inputs["Color2"])
        col = mix.outputs["Color"]
    link(nt, col, b.inputs["Base Color"])
    if rough_img is not None:
        rt = nt.nodes.new("ShaderNodeTexImage")
        rt.image = rough_img
        link(nt, vec, rt.inputs["Vector"])
        mr = nt.nodes.new("ShaderNodeMapRange")
        mr.inputs["To Min"].default_value = rough
        mr.inputs["To Max"].default_value = rough_lo
        link(nt, rt.outputs["Color"], mr.inputs["Value"])
        link(nt, mr.outputs["Result"], b.inputs["Roughness"])
    else:
        b.inputs["Roughness"].default_value = rough
    if bump_img is not None:
        bt = nt.nodes.new("ShaderNodeTexImage")
        bt.image = bump_img
        link(nt, vec, bt.inputs["Vector"])
        bn = nt.nodes.new("ShaderNodeBump")
        bn.inputs["Distance"].default_value = bump
        bn.inputs["Strength"].default_value = 1.0
        link(nt, bt.outputs["Color"], bn.inputs["Height"])
        link(nt, bn.outputs["Normal"], b.inputs["Normal"])
    return m


def mesh_object(name, verts, faces, uvs=None, mats=None, face_mats=None, smooth=False, coll=None):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    if uvs is not None:
        uvl = me.uv_layers.new(name="UVMap")
        data = []
        for f in me.polygons:
            for li in f.loop_indices:
                data.extend(uvs[me.loops[li].vertex_index])
        uvl.data.foreach_set("uv", data)
    if mats:
        for m in mats:
            me.materials.append(m)
        if face_mats is not None:
            me.polygons.foreach_set("material_index", list(face_mats))
    me.polygons.foreach_set("use_smooth", [smooth] * len(me.polygons))
    me.validate()
    me.update()
    ob = bpy.data.objects.new(name, me)
    (coll or bpy.context.scene.collection).objects.link(ob)
    return ob


def cylinder(name, r, h, seg, mat, loc, rot_z=0.0, cap=True, coll=None, r_top=None):
    r_top = r if r_top is None else r_top
    verts, faces, uvs = [], [], []
    for i in range(seg + 1):
        a = 2 * math.pi * i / seg
        verts += [(r * math.cos(a), r * math.sin(a), 0.0), (r_top * math.cos(a), r_top * math.sin(a), h)]
        uvs += [(i / seg, 0.0), (i / seg, 1.0)]
    for i in range(seg):
        faces.append((2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1))
    if cap:
        c = len(verts)
        verts += [(0, 0, h)]
        uvs += [(0.5, 0.5)]
        for i in range(seg):
            faces.append((2 * i + 1, 2 * i + 3, c))
    ob = mesh_object(name, verts, faces, uvs, [mat], smooth=True, coll=coll)
    ob.location = loc
    ob.rotation_euler = (0, 0, rot_z)
    return ob


def box(name, size, loc, mat, rot_z=0.0, coll=None, uv_scale=1.0):
    sx, sy, sz = (s / 2 for s in size)
    v = [(-sx, -sy, -sz), (sx, -sy, -sz), (sx, sy, -sz), (-sx, sy, -sz),
         (-sx, -sy, sz), (sx, -sy, sz), (sx, sy, sz), (-sx, sy, sz)]
    f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    # Separate vertices per face so each face gets its own metric UVs.
    verts, faces, uvs = [], [], []
    for face in f:
        p = [Vector(v[i]) for i in face]
        e1 = (p[1] - p[0])
        e2 = (p[3] - p[0])
        base = len(verts)
        for k, q in enumerate(p):
            d = q - p[0]
            uvs.append((d.dot(e1.normalized()) * uv_scale, d.dot(e2.normalized()) * uv_scale))
            verts.append(tuple(q))
        faces.append(tuple(range(base, base + 4)))
    ob = mesh_object(name, verts, faces, uvs, [mat], coll=coll)
    ob.location = loc
    ob.rotation_euler = (0, 0, rot_z)
    return ob


# ----------------------------------------------------------------------------------------------
# The car (exported to car.glb; not part of the street renders)


def build_car(rng, coll):
    """A sedan: lofted body sections, arches, wheels, lights, plates. Blender frame +X forward,
    +Y left, +Z up; origin at the centre of the wheelbase on the ground."""
    L, W = 4.40, 1.82
    wheelbase, wr, ww = 2.64, 0.325, 0.225
    xw = (wheelbase / 2, -wheelbase / 2)
    palette = [(0.02, 0.09, 0.35), (0.45, 0.03, 0.03), (0.55, 0.55, 0.57), (0.03, 0.16, 0.07),
               (0.60, 0.32, 0.04), (0.02, 0.02, 0.025)]
    paint_col = palette[rng.randrange(len(palette))]
    mats = {
        "CarPaint": principled("CarPaint", paint_col, rough=0.3, metal=0.9),
        "CarGlass": principled("CarGlass", (0.015, 0.018, 0.022), rough=0.05, metal=0.0, spec=0.5),
        "Rubber": principled("Rubber", (0.025, 0.025, 0.025), rough=0.9),
        "RimMetal": principled("RimMetal", (0.75, 0.75, 0.77), rough=0.2, metal=1.0),
        "BlackPlastic": principled("BlackPlastic", (0.035, 0.035, 0.035), rough=0.55),
        "HeadLight": principled("HeadLight", (0.9, 0.9, 0.88), rough=0.1, emission=(1.0, 0.97, 0.9), estrength=1.0),
        "TailLight": principled("TailLight", (0.5, 0.02, 0.02), rough=0.15, emission=(0.6, 0.0, 0.0), estrength=1.0),
    }
    # Licence plate texture: white with black glyph blocks (a base-colour texture in the glTF).
    ph, pw = 32, 144
    plate = np.ones((ph, pw, 3), np.float32) * 0.92
    plate[:2, :] = plate[-2:, :] = plate[:, :2] = plate[:, -2:] = 0.1
    plate[3:-3, 4:14] = (0.1, 0.2, 0.7)
    x = 18
    for _ in range(7):
        gw = 12
        glyph = np.array([[rng.random() < 0.55 for _ in range(3)] for _ in range(5)])
        for gy in range(5):
            for gx in range(3):
                if glyph[gy, gx]:
                    plate[6 + gy * 4:6 + gy * 4 + 4, x + gx * 4:x + gx * 4 + 4] = 0.05
        x += gw + (6 if _ == 2 else 2)
    plate_img = make_image("LicensePlateTex", plate)
    mats["LicensePlate"] = textured("LicensePlate", plate_img, rough=0.4)

    # Side profile (x, z_top) and plan half-width.
    top = [(-2.20, 0.60), (-2.16, 0.86), (-2.02, 0.97), (-1.50, 1.01), (-1.05, 1.38), (-0.85, 1.43),
           (0.30, 1.45), (0.45, 1.41), (1.12, 1.00), (1.80, 0.90), (2.14, 0.80), (2.20, 0.56)]
    belt = [(-2.2, 0.95), (-1.5, 1.0), (1.12, 0.98), (2.2, 0.90)]

    def interp(pts, x):
        xs = [p[0] for p in pts]
        ys = [p[1] for p in pts]
        return float(np.interp(x, xs, ys))

    def half_w(x):
        t = min(1.0, max(0.0, (abs(x) - 1.75) / 0.45))
        return W / 2 * (1.0 - 0.12 * t * t) - 0.02 * (x < 0)

    def z_bot(x):
        z = 0.24 + 0.10 * max(0.0, (abs(x) - 1.85) / 0.35)
        for c in xw:
            d = x - c
            if abs(d) < 0.42:
                z = max(z, wr + math.sqrt(0.42 * 0.42 - d * d) - 0.02)
        return z

    # Stations: denser near the arches and the ends.
    xs = sorted(set([round(v, 4) for v in list(np.linspace(-L / 2, L / 2, 56)) +
                     [c + d for c in xw for d in np.linspace(-0.44, 0.44, 17)]]))
    nside = 11  # points per side, bottom centre excluded, top centre excluded
    sections = []
    for x in xs:
        zt, zb, w = interp(top, x), z_bot(x), half_w(x)
        zbelt = min(interp(belt, x), zt - 0.01)
        green = zt - zbelt  # greenhouse height at this station
        wr_roof = w - 0.10 - 0.25 * min(1.0, green / 0.45)
        pts = [(w - 0.06, zb), (w - 0.01, zb + 0.05), (w, zb + 0.12 * (zbelt - zb) + 0.02),
               (w + 0.01, zb + 0.55 * (zbelt - zb)), (w, zbelt - 0.03), (w - 0.02, zbelt)]
        if green > 0.05:
            for t in (0.33, 0.66, 1.0):
                pts.append((w - 0.02 + (wr_roof - (w - 0.02)) * t, zbelt + (zt - 0.03 - zbelt) * t))
            pts += [(wr_roof * 0.6, zt - 0.005)]
        else:
            for t in (0.25, 0.5, 0.75):
                pts.append((w - 0.02 - 0.08 * t, zbelt + (zt - zbelt) * t))
            pts += [(w * 0.6, zt)]
        pts.append((w * 0.2, zt))
        assert len(pts) == nside
        sections.append((x, zt, zb, zbelt, pts))

    verts, faces, fmat = [], [], []
    per = 2 * nside + 2  # bottom centre, right side (y<0), top centre, left side (y>0)
    for x, zt, zb, zbelt, pts in sections:
        ring = [(x, 0.0, zb)] + [(x, -y, z) for y, z in pts] + [(x, 0.0, zt)] + [(x, y, z) for y, z in reversed(pts)]
        verts += ring
    names = list(mats.keys())

    def mi(n):
        return names.index(n)

    for s in range(len(sections) - 1):
        x0, x1 = sections[s][0], sections[s + 1][0]
        xm = 0.5 * (x0 + x1)
        for k in range(per):
            a, b = s * per + k, s * per + (k + 1) % per
            c, d = (s + 1) * per + (k + 1) % per, (s + 1) * per + k
            faces.append((a, d, c, b))
            zc = (verts[a][2] + verts[b][2] + verts[c][2] + verts[d][2]) / 4
            yc = abs(verts[a][1] + verts[b][1]) / 2
            zbelt = interp(belt, xm)
            zt = interp(top, xm)
            m = "CarPaint"
            if zc > zbelt + 0.015 and zt - zbelt > 0.1:
                roof = -0.95 < xm < 0.38 and yc < half_w(xm) - 0.33
                pillar = (-0.30 < xm < -0.16) or (0.36 < xm < 0.46 and yc > half_w(xm) - 0.32) or \
                    (-1.08 < xm < -0.92 and yc > half_w(xm) - 0.32)
                if not roof and not pillar and zc < zt - 0.012:
                    m = "CarGlass"
            if zc < 0.48 and abs(xm) > 1.78:
                m = "BlackPlastic"
            if zc < zb_min_side(sections, s) + 0.06 and abs(xm) < 1.70 and yc > 0.5:
                m = "BlackPlastic"  # sills
            fmat.append(mi(m))
    # End caps.
    for s, sign in ((0, -1), (len(sections) - 1, 1)):
        base = s * per
        c = len(verts)
        x, zt, zb = sections[s][0], sections[s][1], sections[s][2]
        verts.append((x, 0.0, 0.5 * (zt + zb)))
        for k in range(per):
            a, b = base + k, base + (k + 1) % per
            faces.append((a, b, c) if sign < 0 else (b, a, c))
            fmat.append(mi("BlackPlastic" if verts[a][2] < 0.48 else "CarPaint"))
    coll_objs = []
    body = mesh_object("Body", verts, faces, None, [mats[n] for n in names], fmat, smooth=True, coll=coll)
    coll_objs.append(body)

    # Wheels: tyre (open cylinder with sidewalls), rim disc with five spokes, hub.
    seg = 28
    for i, (xc, yc) in enumerate([(xw[0], 1), (xw[0], -1), (xw[1], 1), (xw[1], -1)]):
        v, f, fm = [], [], []
        y_out = yc * (W / 2 - 0.02)
        y_in = y_out - yc * ww
        r_in = wr * 0.68
        rings = [(y_in, r_in), (y_in, wr * 0.93), (y_in + yc * 0.03, wr), (y_out - yc * 0.03, wr),
                 (y_out, wr * 0.93), (y_out, r_in)]
        for y, r in rings:
            for j in range(seg):
                a = 2 * math.pi * j / seg
                v.append((xc + r * math.cos(a), y, wr + r * math.sin(a)))
        for ri in range(len(rings) - 1):
            for j in range(seg):
                a, b = ri * seg + j, ri * seg + (j + 1) % seg
                quad = (a, b, b + seg, a + seg)
                f.append(quad if yc < 0 else quad[::-1])
                fm.append(0)
        # Rim: a recessed disc (metal) inside the tyre's inner radius.
        cidx = len(v)
        y_rim = y_out - yc * 0.05
        v.append((xc, y_rim + yc * 0.02, wr))
        for j in range(seg):
            a = 2 * math.pi * j / seg
            v.append((xc + r_in * math.cos(a), y_rim, wr + r_in * math.sin(a)))
        for j in range(seg):
            a, b = cidx + 1 + j, cidx + 1 + (j + 1) % seg
            f.append((a, b, cidx) if yc < 0 else (b, a, cidx))
            fm.append(1)
        # Connect the rim's edge to the tyre's outer inner ring.
        last = (len(rings) - 1) * seg
        for j in range(seg):
            a, b = last + j, last + (j + 1) % seg
            q = (a, b, cidx + 1 + (j + 1) % seg, cidx + 1 + j)
            f.append(q if yc < 0 else q[::-1])
            fm.append(1)
        wob = mesh_object(f"Wheel{i}", v, f, None, [mats["Rubber"], mats["RimMetal"]], fm, smooth=True, coll=coll)
        coll_objs.append(wob)
        # Spokes: dark slots between five rim spokes, as thin boxes just outside the rim face.
        for k in range(5):
            a = 2 * math.pi * (k + 0.5) / 5
            sp = box(f"Slot{i}_{k}", (0.055, 0.004, 0.12), (xc + 0.13 * math.cos(a), y_rim + yc * 0.012,
                                                            wr + 0.13 * math.sin(a)), mats["BlackPlastic"], coll=coll)
            sp.rotation_euler = (0.0, -a + math.pi / 2, 0.0)
            coll_objs.append(sp)

    # Lights and plates, slightly proud of the body surface.
    def surface_x(y, z, front):
        # March along x from the end until inside the body's section at (y, z).
        xs_ = np.linspace(L / 2, 0, 400) if front else np.linspace(-L / 2, 0, 400)
        for x in xs_:
            zb, zt = z_bot(x), interp(top, x)
            if zb < z < zt and abs(y) < half_w(x) - 0.05:
                return float(x)
        return float(xs_[-1])

    for side in (1, -1):
        xf = surface_x(0.62 * side, 0.72, True)
        coll_objs.append(box(f"HeadLight{side}", (0.06, 0.30, 0.09), (xf + 0.005, 0.60 * side, 0.72),
                             mats["HeadLight"], coll=coll))
        xr = surface_x(0.66 * side, 0.84, False)
        coll_objs.append(box(f"TailLight{side}", (0.06, 0.26, 0.10), (xr - 0.005, 0.66 * side, 0.84),
                             mats["TailLight"], coll=coll))
    for front in (True, False):
        xp = surface_x(0.0, 0.40, front)
        sgn = 1 if front else -1
        v = [(xp + sgn * 0.012, -0.26 * sgn, 0.345), (xp + sgn * 0.012, 0.26 * sgn, 0.345),
             (xp + sgn * 0.012, 0.26 * sgn, 0.455), (xp + sgn * 0.012, -0.26 * sgn, 0.455)]
        uv = [(0, 0), (1, 0), (1, 1), (0, 1)]
        coll_objs.append(mesh_object("PlateFront" if front else "PlateRear", v, [(0, 1, 2, 3)], uv,
                                     [mats["LicensePlate"]], coll=coll))
    # Mirrors.
    for side in (1, -1):
        m = box(f"Mirror{side}", (0.12, 0.16, 0.10), (0.62, side * (half_w(0.62) + 0.07), 1.03),
                mats["CarPaint"], coll=coll)
        coll_objs.append(m)
    return coll_objs, {"length_m": L, "width_m": W, "height_m": 1.45, "wheelbase_m": wheelbase,
                       "wheel_radius_m": wr, "paint_rgb": list(paint_col), "materials": names}


def zb_min_side(sections, s):
    return min(sections[s][2], sections[s + 1][2])


def export_car(path, rng):
    coll = bpy.data.collections.new("Car")
    bpy.context.scene.collection.children.link(coll)
    objs, info = build_car(rng, coll)
    bpy.ops.object.select_all(action="DESELECT")
    for o in objs:
        o.select_set(True)
    bpy.context.view_layer.objects.active = objs[0]
    bpy.ops.export_scene.gltf(filepath=path, export_format="GLB", use_selection=True, export_yup=True,
                              export_apply=True, export_texcoords=True, export_normals=True,
                              export_materials="EXPORT", export_image_format="AUTO", export_cameras=False,
                              export_lights=False, export_extras=False, export_animations=False)
    for o in objs:
        bpy.data.objects.remove(o, do_unlink=True)
    bpy.data.collections.remove(coll)
    return info


# ----------------------------------------------------------------------------------------------
# The street


class Road:
    """Centreline parameterised by arc length s: straight, a clothoid-eased left bend, straight."""

    def __init__(self, rng):
        self.s_min, self.s_max = -45.0, 120.0
        self.bend_start = rng.uniform(24.0, 30.0)
        self.bend_len = rng.uniform(30.0, 40.0)
        self.bend_angle = math.radians(rng.uniform(22.0, 32.0)) * (1 if rng.random() < 0.5 else -1)
        self.ease = 10.0
        ds = 0.05
        n = int((self.s_max - self.s_min) / ds) + 1
        self.ds = ds
        s = self.s_min + ds * np.arange(n)
        k = np.array([self.curvature(v) for v in s])
        h = np.concatenate([[0.0], np.cumsum(0.5 * (k[1:] + k[:-1]) * ds)])
        h -= np.interp(0.0, s, h)  # heading 0 (+X) at s = 0
        x = np.concatenate([[0.0], np.cumsum(0.5 * (np.cos(h[1:]) + np.cos(h[:-1])) * ds)])
        y = np.concatenate([[0.0], np.cumsum(0.5 * (np.sin(h[1:]) + np.sin(h[:-1])) * ds)])
        x -= np.interp(0.0, s, x)
        y -= np.interp(0.0, s, y)
        self.s, self.h, self.x, self.y = s, h, x, y

    def curvature(self, s):
        # Trapezoidal curvature: eased in and out over `ease` metres (no kinks in the heading).
        a, L, e = self.bend_start, self.bend_len, self.ease
        kmax = self.bend_angle / (L - e)
        if s < a or s > a + L:
            return 0.0
        if s < a + e:
            return kmax * (s - a) / e
        if s > a + L - e:
            return kmax * (a + L - s) / e
        return kmax

    def at(self, s, lateral=0.0):
        """(x, y, heading) at arc length s, lateral offset (> 0 = left)."""
        h = float(np.interp(s, self.s, self.h))
        x = float(np.interp(s, self.s, self.x)) - lateral * math.sin(h)
        y = float(np.interp(s, self.s, self.y)) + lateral * math.cos(h)
        return x, y, h


def strip(name, road, s0, s1, laterals, zs, mat, uv_fn, step=1.0, coll=None):
    """A mesh swept along the road: cross-section points (lateral, z) from laterals/zs."""
    n = max(2, int(math.ceil((s1 - s0) / step)) + 1)
    ss = np.linspace(s0, s1, n)
    verts, uvs, faces = [], [], []
    m = len(laterals)
    for s in ss:
        for l, z in zip(laterals, zs):
            x, y, _ = road.at(s, l)
            verts.append((x, y, z))
            uvs.append(uv_fn(s, l, z))
    for i in range(n - 1):
        for j in range(m - 1):
            a, b = i * m + j, i * m + j + 1
            # Cross-sections run left to right (increasing lateral, with vertical kerb steps), so
            # this winding puts normals up on flat parts and towards the road on kerb faces.
            faces.append((a, a + m, b + m, b))
    return mesh_object(name, verts, faces, uvs, [mat], coll=coll)


def tex_asphalt(rng, n=1024):
    base = 0.36 + 0.035 * periodic_noise(rng, n, n, 2.2) + 0.025 * periodic_noise(rng, n, n, 0.2)
    grain = rng.random((n, n))
    base = np.where(grain > 0.993, base + 0.18, base)  # bright aggregate
    base = np.where(grain < 0.005, base - 0.12, base)
    # Cracks: random walks.
    crack = np.zeros((n, n), np.float32)
    for _ in range(14):
        y, x = rng.integers(0, n, 2)
        a = rng.uniform(0, 2 * np.pi)
        for _ in range(rng.integers(80, 400)):
            a += rng.normal(0, 0.35)
            x = (x + int(round(2 * np.cos(a)))) % n
            y = (y + int(round(2 * np.sin(a)))) % n
            crack[y, x] = 1
            crack[(y + 1) % n, x] = 0.6
    # Patches (repairs), darker and smoother.
    patch = np.zeros((n, n), np.float32)
    for _ in range(4):
        cy, cx = rng.integers(0, n, 2)
        hh, ww = rng.integers(40, 160, 2)
        yy = (np.arange(cy, cy + hh) % n)[:, None]
        xx = (np.arange(cx, cx + ww) % n)[None, :]
        patch[yy, xx] = 1
    g = base * (1 - 0.25 * patch) - 0.2 * crack
    col = np.stack([g * 0.97, g * 0.98, g * 1.02], axis=2)
    bump = 0.5 + 0.12 * (grain - 0.5) - 0.4 * crack
    return np.clip(col, 0, 1), np.clip(bump, 0, 1)


def tex_paving(rng, n=512, tiles=10, tint=(0.62, 0.60, 0.56)):
    t = n // tiles
    yy, xx = np.mgrid[0:n, 0:n]
    ti = np.minimum(yy // t, tiles - 1) * tiles + np.minimum(xx // t, tiles - 1)
    jit = rng.normal(0, 0.045, tiles * tiles + 1)[ti]
    g = 1.0 + jit + 0.05 * periodic_noise(rng, n, n, 1.0) + 0.06 * periodic_noise(rng, n, n, 2.5)
    joint = ((yy % t) < 2) | ((xx % t) < 2)
    g = np.where(joint, 0.55, g)
    col = np.stack([g * tint[0], g * tint[1], g * tint[2]], axis=2)
    bump = np.where(joint, 0.0, 0.8 + 0.05 * periodic_noise(rng, n, n, 1.0))
    return np.clip(col, 0, 1), np.clip(bump, 0, 1)


def tex_gravel(rng, n=512):
    g = 0.42 + 0.06 * periodic_noise(rng, n, n, 0.8) + 0.05 * periodic_noise(rng, n, n, 2.5)
    col = np.stack([g * 1.0, g * 0.95, g * 0.82], axis=2)
    return np.clip(col, 0, 1)


FACADE_PX_PER_M = 32


def tex_facade(rng, w_m, h_m, style):
    """Unique facade texture: wall pattern, windows per floor and bay, shop front and sign band.
    Returns sRGB colour, glass mask and height map, top-down arrays."""
    ppm = FACADE_PX_PER_M
    W, H = max(16, int(round(w_m * ppm))), max(16, int(round(h_m * ppm)))
    yy, xx = np.mgrid[0:H, 0:W]
    zz = (H - 1 - yy) / ppm  # metres above the ground
    xm = xx / ppm
    palettes = {
        "brick": [(0.55, 0.27, 0.18), (0.62, 0.35, 0.24), (0.48, 0.24, 0.20), (0.66, 0.45, 0.33)],
        "plaster": [(0.86, 0.80, 0.66), (0.78, 0.62, 0.45), (0.72, 0.76, 0.78), (0.88, 0.84, 0.78),
                    (0.70, 0.52, 0.50), (0.64, 0.70, 0.58)],
        "panel": [(0.58, 0.60, 0.62), (0.45, 0.47, 0.50), (0.70, 0.68, 0.63)],
        "stone": [(0.74, 0.68, 0.58), (0.66, 0.63, 0.60)],
    }
    base = np.array(palettes[style][rng.integers(len(palettes[style]))], np.float32)
    height = np.full((H, W), 0.7, np.float32)
    if style == "brick":
        bw, bh = 0.42, 0.16
        row = np.floor(zz / bh).astype(int)
        off = (row % 2) * bw / 2
        col = np.floor((xm + off) / bw).astype(int)
        ids = (row * 1009 + col * 7919) % 65521
        jit = rng.normal(0, 0.06, 65521)[ids]
        mortar = ((zz % bh) < 0.035) | (((xm + off) % bw) < 0.035)
        g = 1 + jit
        height = np.where(mortar, 0.45, 0.75)
        colr = base[None, None, :] * g[:, :, None]
        colr = np.where(mortar[:, :, None], np.array([0.70, 0.68, 0.64]), colr)
    elif style in ("panel", "stone"):
        pw, ph = (1.6, 1.1) if style == "panel" else (0.75, 0.38)
        row = np.floor(zz / ph).astype(int)
        off = (row % 2) * pw / 2 if style == "stone" else 0
        col = np.floor((xm + off) / pw).astype(int)
        ids = (row * 1009 + col * 7919) % 65521
        jit = rng.normal(0, 0.06, 65521)[ids]
        seam = ((zz % ph) < 0.04) | (((xm + off) % pw) < 0.04)
        colr = base[None, None, :] * (1 + jit)[:, :, None]
        colr = np.where(seam[:, :, None], base * 0.55, colr)
        height = np.where(seam, 0.45, 0.75)
    else:
        colr = base[None, None, :] * (1 + 0.05 * periodic_noise(rng, H, W, 1.6))[:, :, None]
    # Grain and grime for tracking texture: fine noise, stains, darker near the ground.
    colr = colr * (1 + 0.025 * periodic_noise(rng, H, W, 0.3))[:, :, None]
    colr = colr * (1 + 0.08 * periodic_noise(rng, H, W, 2.2))[:, :, None]
    colr = colr * (1 - 0.18 * np.exp(-zz / 0.8))[:, :, None]

    ground_h = rng.uniform(3.8, 4.6)
    floor_h = rng.uniform(3.0, 3.5)
    bay = rng.uniform(2.2, 3.2)
    nb = max(1, int(w_m / bay))
    bay = w_m / nb
    win_w = bay * rng.uniform(0.42, 0.6)
    win_h = floor_h * rng.uniform(0.45, 0.6)
    sill = rng.uniform(0.8, 1.0)
    frame_col = np.array([(0.92, 0.92, 0.90), (0.15, 0.14, 0.13), (0.35, 0.22, 0.14), (0.5, 0.52, 0.55)]
                         [rng.integers(4)])
    mask = np.zeros((H, W), np.float32)
    floors = int((h_m - ground_h - 0.6) / floor_h)
    fr = 0.07
    for f in range(floors):
        z0 = ground_h + f * floor_h + sill
        for b in range(nb):
            if rng.random() < 0.04:
                continue  # a blind bay
            x0 = b * bay + (bay - win_w) / 2
            inwin = (xm >= x0) & (xm < x0 + win_w) & (zz >= z0) & (zz < z0 + win_h)
            inglass = (xm >= x0 + fr) & (xm < x0 + win_w - fr) & (zz >= z0 + fr) & (zz < z0 + win_h - fr)
            frame = inwin & ~inglass
            colr[frame] = frame_col
            # Glass: dark, a vertical gradient, sometimes a blind or curtain, sometimes lit.
            t = (zz[inglass] - z0) / win_h
            g = np.array([0.10, 0.13, 0.17]) * (0.7 + 0.6 * t)[:, None]
            kind = rng.random()
            if kind < 0.3:  # blind pulled down part-way
                blind = t > rng.uniform(0.3, 0.9)
                bc = np.array([(0.85, 0.83, 0.76), (0.6, 0.55, 0.45), (0.75, 0.78, 0.8)][rng.integers(3)])
                stripes = ((zz[inglass] * ppm).astype(int) % 3 == 0)
                g = np.where(blind[:, None], bc * np.where(stripes, 0.85, 1.0)[:, None], g)
            elif kind < 0.42:  # curtains at both sides
                u = (xm[inglass] - x0) / win_w
                cur = (u < 0.25) | (u > 0.75)
                cc = np.array([(0.7, 0.2, 0.15), (0.8, 0.75, 0.6), (0.25, 0.35, 0.55)][rng.integers(3)])
                g = np.where(cur[:, None], cc * (0.8 + 0.2 * np.sin(xm[inglass] * 40))[:, None], g)
            elif kind < 0.5:
                g = g * 0.6 + np.array([0.55, 0.45, 0.30])
            colr[inglass] = g
            # Mullion cross on some styles.
            if style in ("brick", "stone") and win_w > 1.0:
                mull = inglass & (np.abs(xm - (x0 + win_w / 2)) < 0.035)
                colr[mull] = frame_col
                inglass = inglass & ~mull
            mask[inglass] = 1.0
            height[inwin] = 0.3
            height[inglass] = 0.1
            # Sill below the window, lighter.
            sl = (xm >= x0 - 0.08) & (xm < x0 + win_w + 0.08) & (zz >= z0 - 0.12) & (zz < z0)
            colr[sl] = np.clip(base * 1.25, 0, 1) if style != "brick" else np.array([0.8, 0.78, 0.74])
            height[sl] = 0.95
        # String course between floors.
        if style in ("plaster", "stone"):
            sc = (zz >= ground_h + f * floor_h - 0.1) & (zz < ground_h + f * floor_h + 0.05)
            colr[sc] = colr[sc] * 0.82
    # Ground floor: shop front with a sign band, or a plain entrance.
    shop = rng.random() < 0.75
    if shop:
        sign_z = ground_h - 0.9
        sign = (zz >= sign_z) & (zz < sign_z + 0.7) & (xm > 0.3) & (xm < w_m - 0.3)
        sc = np.array([(0.75, 0.10, 0.10), (0.10, 0.25, 0.60), (0.10, 0.45, 0.25), (0.90, 0.70, 0.10),
                       (0.12, 0.12, 0.12), (0.85, 0.85, 0.85)][rng.integers(6)])
        colr[sign] = sc
        # Letters: blocky glyphs in a contrasting colour.
        lc = np.array([0.95, 0.95, 0.92]) if sc.mean() < 0.5 else np.array([0.08, 0.08, 0.1])
        nlet = int(min(14, (w_m - 1.5) / 0.45))
        x = (w_m - nlet * 0.45) / 2
        for _ in range(nlet):
            if rng.random() < 0.12:
                x += 0.45
                continue
            glyph = rng.random((5, 3)) < 0.55
            for gy in range(5):
                for gx in range(3):
                    if glyph[gy, gx]:
                        cell = ((xm >= x + gx * 0.1) & (xm < x + gx * 0.1 + 0.1) &
                                (zz >= sign_z + 0.6 - (gy + 1) * 0.1) & (zz < sign_z + 0.6 - gy * 0.1))
                        colr[cell] = lc
            x += 0.45
        height[sign] = 0.9
        # Shop windows and a door.
        nsw = max(1, int(w_m / 3.2))
        sww = w_m / nsw
        door = rng.integers(nsw)
        for i in range(nsw):
            x0, x1 = i * sww + 0.25, (i + 1) * sww - 0.25
            z1 = sign_z - 0.15
            z0 = 0.05 if i == door else 0.55
            inwin = (xm >= x0) & (xm < x1) & (zz >= z0) & (zz < z1)
            inglass = (xm >= x0 + 0.08) & (xm < x1 - 0.08) & (zz >= z0 + 0.08) & (zz < z1 - 0.08)
            colr[inwin & ~inglass] = frame_col * 0.6
            t = (zz[inglass] - z0) / (z1 - z0)
            g = np.array([0.10, 0.12, 0.14]) * (0.6 + 0.8 * t)[:, None]
            # Goods behind the glass: random coloured blocks.
            for _ in range(rng.integers(3, 9)):
                bx, bz = rng.uniform(x0, x1 - 0.4), rng.uniform(z0, z1 - 0.6)
                bwid, bhei = rng.uniform(0.15, 0.5), rng.uniform(0.2, 0.7)
                blk = ((xm[inglass] >= bx) & (xm[inglass] < bx + bwid) & (zz[inglass] >= bz) &
                       (zz[inglass] < bz + bhei))
                g = np.where(blk[:, None], rng.uniform(0.1, 0.7, 3) * 0.6, g)
            colr[inglass] = g
            mask[inglass] = 1.0
            height[inglass] = 0.1
    else:
        dx = rng.uniform(0.5, max(0.6, w_m - 2.0))
        door = (xm >= dx) & (xm < dx + 1.3) & (zz < 2.4)
        colr[door] = np.array([(0.25, 0.15, 0.08), (0.1, 0.2, 0.3), (0.2, 0.2, 0.2)][rng.integers(3)])
        height[door] = 0.2
    # Cornice.
    cor = zz > h_m - 0.45
    colr[cor] = colr[cor] * 0.75
    height[cor] = 0.95
    return np.clip(colr, 0, 1), mask, np.clip(height, 0, 1)


def build_street(args, rng, nrng, coll):
    road = Road(rng)
    layout = {"buildings": [], "trees": [], "poles": [], "signs": [], "parked": [], "props": []}
    road_w = rng.uniform(7.4, 8.2)
    lane_w = road_w / 2
    side_w = rng.uniform(2.8, 3.6)
    kerb = 0.15
    s0, s1 = road.s_min, road.s_max
    t0 = time.time()

    asphalt, _ = tex_asphalt(nrng)
    m_road = textured("Asphalt", make_image("asphalt", asphalt), rough=0.85, noise_mod=0.12, noise_scale=0.08,
                      spec=0.4)
    road_tile = 16.0
    strip("Road", road, s0, s1, [-road_w / 2, road_w / 2], [0.0, 0.0], m_road,
          lambda s, l, z: (l / road_tile, s / road_tile), coll=coll)
    tint = [(0.62, 0.60, 0.56), (0.58, 0.55, 0.52)]
    m_side = [textured(f"Paving{i}", make_image(f"paving{i}", tex_paving(nrng, tint=tint[i])[0]), rough=0.8,
                       noise_mod=0.15, noise_scale=0.15) for i in range(2)]
    kerb_mat = principled("Kerb", (0.55, 0.55, 0.53), rough=0.7)
    for i, side in enumerate((1, -1)):
        a, b = road_w / 2, road_w / 2 + side_w
        lat = [side * a, side * a, side * b]
        zs = [0.0, kerb, kerb]
        if side < 0:
            lat, zs = lat[::-1], zs[::-1]
        strip(f"Sidewalk{i}", road, s0, s1, lat, zs, m_side[i], lambda s, l, z: (l / 4.0 + z, s / 4.0), coll=coll)
        # Kerb stones: a light band along the edge.
        strip(f"KerbTop{i}", road, s0, s1, sorted([side * a, side * (a + 0.2)]), [kerb + 0.002] * 2, kerb_mat,
              lambda s, l, z: (l, s), coll=coll)
    # Backyard ground at sidewalk level, far out.
    gravel = make_image("gravel", tex_gravel(nrng))
    m_ground = textured("Ground", gravel, rough=0.9, coord="OBJECT", scale=0.2, noise_mod=0.2, noise_scale=0.03)
    # At kerb height beyond the sidewalks (under and between the buildings), and a plane just
    # below the road surface for whatever lies further out.
    for i, side in enumerate((1, -1)):
        lat = sorted([side * (road_w / 2 + side_w), side * 55.0])
        strip(f"Ground{i}", road, s0 - 40, s1 + 40, lat, [kerb - 0.002] * 2, m_ground, lambda s_, l, z: (l, s_),
              step=2.0, coll=coll)
    g = 400.0
    mesh_object("GroundFar", [(-g, -g, -0.02), (g, -g, -0.02), (g, g, -0.02), (-g, g, -0.02)],
                [(0, 1, 2, 3)], [(0, 0), (1, 0), (1, 1), (0, 1)], [m_ground], coll=coll)
    # Road beyond the modelled street ends (under the end buildings).
    # Markings: edge lines, dashed centre line, zebra crossing, stop lines.
    m_paint = principled("RoadPaint", (0.85, 0.85, 0.82), rough=0.6)
    m_yellow = principled("RoadPaintYellow", (0.85, 0.65, 0.1), rough=0.6)
    zmark = 0.004
    for side in (1, -1):
        l = side * (road_w / 2 - 0.35)
        strip(f"EdgeLine{side}", road, s0, s1, sorted([l - 0.06, l + 0.06]), [zmark] * 2, m_paint,
              lambda s, l_, z: (0, 0), coll=coll)
    dash, gap = 3.0, 5.0
    s = s0 + rng.uniform(0, gap)
    k = 0
    while s < s1 - dash:
        strip(f"Dash{k}", road, s, s + dash, [-0.06, 0.06], [zmark] * 2, m_paint, lambda s_, l, z: (0, 0), step=1.0,
              coll=coll)
        s += dash + gap
        k += 1
    zebra_s = rng.uniform(12.0, 16.0)
    for i in range(int(road_w / 1.0)):
        l0 = -road_w / 2 + 0.25 + i * 1.0
        strip(f"Zebra{i}", road, zebra_s, zebra_s + 3.0, [l0, l0 + 0.5], [zmark] * 2, m_paint,
              lambda s_, l, z: (0, 0), step=0.5, coll=coll)
    for side, ss in ((-1, zebra_s - 1.5), (1, zebra_s + 4.2)):
        lat = sorted([0.0, side * (road_w / 2 - 0.1)])
        strip(f"StopLine{side}", road, ss, ss + 0.35, lat, [zmark] * 2, m_paint, lambda s_, l, z: (0, 0), step=0.35,
              coll=coll)
    # A yellow box junction hatch further on (unique features on the road).
    hs = zebra_s + rng.uniform(28, 34)
    for i in range(6):
        strip(f"Hatch{i}", road, hs + i * 0.8, hs + i * 0.8 + 0.25, [-road_w / 2 + 0.4, -0.3], [zmark] * 2, m_yellow,
              lambda s_, l, z: (0, 0), step=0.25, coll=coll)
    # Manholes and drains.
    m_iron = principled("Iron", (0.12, 0.12, 0.13), rough=0.5, metal=0.8)
    for i in range(6):
        ms = rng.uniform(s0 + 10, s1 - 10)
        ml = rng.uniform(-road_w / 2 + 0.8, road_w / 2 - 0.8)
        x, y, h = road.at(ms, ml)
        cylinder(f"Manhole{i}", 0.32, 0.006, 20, m_iron, (x, y, 0.0), cap=True, coll=coll)
    for i in range(10):
        ms = s0 + 12 * i + rng.uniform(0, 4)
        side = 1 if i % 2 else -1
        x, y, h = road.at(ms, side * (road_w / 2 - 0.25))
        box(f"Drain{i}", (0.6, 0.35, 0.01), (x, y, 0.002), m_iron, rot_z=h, coll=coll)

    # Buildings along both sides, then an end block across each end of the street.
    styles = ["brick", "plaster", "panel", "stone", "plaster", "brick"]
    m_side_walls = [textured(f"SideWall{i}", make_image(f"sidewall{i}", np.clip(
        np.array(c)[None, None, :] * (1 + 0.07 * periodic_noise(nrng, 256, 256, 1.5))[:, :, None], 0, 1)),
        rough=0.9, noise_mod=0.15, noise_scale=0.1)
        for i, c in enumerate([(0.7, 0.66, 0.6), (0.55, 0.5, 0.46), (0.62, 0.62, 0.64)])]
    m_roof = principled("Roof", (0.18, 0.18, 0.19), rough=0.8)
    bidx = 0

    def add_building(s_c, side, width, depth, height, setback, style, endcap=0):
        nonlocal bidx
        col, mask, hgt = tex_facade(nrng, width, height, style)
        m = textured(f"Facade{bidx}", make_image(f"facade{bidx}", col), rough=0.85,
                     rough_img=make_image(f"facade_glass{bidx}", mask, True), rough_lo=0.06,
                     bump_img=make_image(f"facade_h{bidx}", hgt, True), bump=0.04,
                     spec=0.5)
        if endcap:
            x, y, h = road.at(s_c, 0.0)
            h_face = h + (math.pi if endcap > 0 else 0.0)  # the facade faces back along the street
            fx, fy = x, y
        else:
            x, y, h = road.at(s_c, side * (road_w / 2 + side_w + setback))
            h_face = h - math.pi / 2 if side > 0 else h + math.pi / 2
            fx, fy = x, y
        # Outward facade normal n = (cos h_face, sin h_face); u runs left to right as seen by a
        # viewer facing the facade (n rotated +90 deg), so the texture is not mirrored.
        onx, ony = math.cos(h_face), math.sin(h_face)
        ux, uy = -ony, onx
        c = [(fx - ux * width / 2, fy - uy * width / 2), (fx + ux * width / 2, fy + uy * width / 2)]
        back = [(px - onx * depth, py - ony * depth) for px, py in c]
        z0, z1 = 0.0, height
        v = [(*c[0], z0), (*c[1], z0), (*c[1], z1), (*c[0], z1),  # front
             (*back[1], z0), (*back[0], z0), (*back[0], z1), (*back[1], z1)]
        # Faces: front (0), right side, back, left side (1), roof (2); per-face vertices for UVs.
        quads = [((0, 1, 2, 3), 0), ((1, 4, 7, 2), 1), ((4, 5, 6, 7), 1), ((5, 0, 3, 6), 1), ((3, 2, 7, 6), 2)]
        verts, faces, uvs, fm = [], [], [], []
        for q, mi_ in quads:
            base = len(verts)
            p = [Vector(v[i]) for i in q]
            e1 = (p[1] - p[0])
            e2 = (p[3] - p[0])
            for qq in p:
                d = qq - p[0]
                if mi_ == 0:
                    uvs.append((d.dot(e1) / e1.length_squared, d.dot(e2) / e2.length_squared))
                else:
                    uvs.append((d.dot(e1.normalized()) / 6.0, d.dot(e2.normalized()) / 6.0))
                verts.append(tuple(qq))
            faces.append(tuple(range(base, base + 4)))
            fm.append(mi_)
        mesh_object(f"Building{bidx}", verts, faces, uvs, [m, m_side_walls[bidx % 3], m_roof], fm, coll=coll)
        layout["buildings"].append({"s_center": round(s_c, 3), "side": side, "width": round(width, 3),
                                    "height": round(height, 3), "depth": round(depth, 3),
                                    "setback": round(setback, 3), "facade": style, "endcap": endcap,
                                    "front_center_world": [round(fx, 3), round(fy, 3), 0.0]})
        bidx += 1

    for side in (1, -1):
        s = s0 + 3.0
        while s < s1 - 6:
            width = rng.uniform(7.0, 15.0)
            gap = rng.uniform(0.0, 2.5) if rng.random() < 0.6 else 0.0
            height = rng.uniform(7.0, 21.0)
            depth = rng.uniform(9.0, 14.0)
            setback = rng.uniform(0.0, 0.6)
            add_building(s + width / 2, side, width, depth, height, setback, styles[rng.randrange(len(styles))])
            s += width + gap
    for end, sgn in ((s0 + 1.0, -1), (s1 - 1.0, 1)):
        add_building(end, 0, road_w + 2 * side_w + 16.0, 12.0, rng.uniform(12, 20), 0.0,
                     styles[rng.randrange(len(styles))], endcap=sgn)
    # A second row of plain tall blocks behind, so gaps do not open onto an empty plain.
    m_far = [principled(f"FarBlock{i}", c, rough=0.9) for i, c in
             enumerate([(0.55, 0.52, 0.48), (0.42, 0.44, 0.47), (0.6, 0.57, 0.5)])]
    for side in (1, -1):
        s = s0
        while s < s1:
            w = rng.uniform(10, 20)
            x, y, h = road.at(s + w / 2, side * (road_w / 2 + side_w + 16 + rng.uniform(0, 4)))
            hh = rng.uniform(14, 30)
            box(f"Far{side}_{int(s)}", (w, 10, hh), (x, y, hh / 2), m_far[rng.randrange(3)], rot_z=h, coll=coll)
            s += w

    # Street furniture.
    m_pole = principled("PoleMetal", (0.25, 0.27, 0.28), rough=0.4, metal=0.7)
    m_lamp = principled("LampGlass", (0.9, 0.9, 0.85), rough=0.2)
    s = s0 + rng.uniform(4, 10)
    k = 0
    while s < s1 - 4:
        side = 1 if k % 2 == 0 else -1
        x, y, h = road.at(s, side * (road_w / 2 + 0.5))
        ph = rng.uniform(6.0, 7.5)
        cylinder(f"Pole{k}", 0.08, ph, 12, m_pole, (x, y, kerb), coll=coll, r_top=0.055)
        # Arm over the road and the lamp head.
        ax, ay = -math.sin(h) * -side, math.cos(h) * -side
        arm = box(f"Arm{k}", (1.6, 0.06, 0.06), (x + ax * 0.8, y + ay * 0.8, kerb + ph - 0.1), m_pole,
                  rot_z=h + math.pi / 2, coll=coll)
        box(f"LampHead{k}", (0.6, 0.28, 0.12), (x + ax * 1.55, y + ay * 1.55, kerb + ph - 0.18), m_lamp,
            rot_z=h + math.pi / 2, coll=coll)
        layout["poles"].append({"s": round(s, 3), "side": side, "height": round(ph, 3),
                                "base_world": [round(x, 3), round(y, 3), kerb]})
        s += rng.uniform(16, 22)
        k += 1
    # Trees in pits on the sidewalks.
    m_bark = textured("Bark", make_image("bark", np.clip(np.stack(
        [0.30 + 0.08 * periodic_noise(nrng, 128, 128, 1.2)] * 3, axis=2) * np.array([1.0, 0.8, 0.6]), 0, 1)),
        rough=0.9, scale=3.0)
    m_leaf = []
    for i, c in enumerate([(0.10, 0.28, 0.06), (0.16, 0.32, 0.08), (0.08, 0.22, 0.07)]):
        m = bpy.data.materials.new(f"Foliage{i}")
        m.use_nodes = True
        nt = m.node_tree
        b = nt.nodes["Principled BSDF"]
        b.inputs["Roughness"].default_value = 0.7
        vor = nt.nodes.new("ShaderNodeTexVoronoi")
        vor.inputs["Scale"].default_value = 9.0
        nz = nt.nodes.new("ShaderNodeTexNoise")
        nz.inputs["Scale"].default_value = 3.0
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].color = (c[0] * 0.45, c[1] * 0.45, c[2] * 0.45, 1)
        ramp.color_ramp.elements[1].color = (c[0] * 1.6, c[1] * 1.5, c[2] * 1.3, 1)
        mixv = nt.nodes.new("ShaderNodeMath")
        mixv.operation = "MULTIPLY"
        link(nt, vor.outputs["Distance"], mixv.inputs[0])
        link(nt, nz.outputs["Fac"], mixv.inputs[1])
        mixv.inputs[1].default_value = 1.0
        mr = nt.nodes.new("ShaderNodeMath")
        mr.operation = "MULTIPLY_ADD"
        link(nt, mixv.outputs[0], mr.inputs[0])
        mr.inputs[1].default_value = 1.6
        mr.inputs[2].default_value = 0.05
        link(nt, mr.outputs[0], ramp.inputs["Fac"])
        link(nt, ramp.outputs["Color"], b.inputs["Base Color"])
        bn = nt.nodes.new("ShaderNodeBump")
        bn.inputs["Distance"].default_value = 0.05
        link(nt, vor.outputs["Distance"], bn.inputs["Height"])
        link(nt, bn.outputs["Normal"], b.inputs["Normal"])
        m_leaf.append(m)
    m_pit = principled("TreePit", (0.16, 0.12, 0.09), rough=0.95)
    s = s0 + rng.uniform(2, 6)
    k = 0
    while s < s1 - 2:
        for side in (1, -1):
            if rng.random() < 0.3:
                continue
            ss = s + rng.uniform(-1.5, 1.5)
            x, y, h = road.at(ss, side * (road_w / 2 + 1.2))
            th = rng.uniform(2.3, 3.4)
            cylinder(f"Trunk{k}", rng.uniform(0.1, 0.16), th + 0.6, 10, m_bark, (x, y, kerb), coll=coll, r_top=0.07)
            box(f"Pit{k}", (1.1, 1.1, 0.01), (x, y, kerb + 0.001), m_pit, rot_z=h, coll=coll)
            cr = rng.uniform(1.2, 1.8)
            for j in range(rng.randint(4, 6)):
                bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, radius=cr * rng.uniform(0.55, 0.85),
                                                      location=(x + rng.uniform(-0.6, 0.6) * cr,
                                                                y + rng.uniform(-0.6, 0.6) * cr,
                                                                kerb + th + cr * rng.uniform(0.2, 1.0)))
                ob = bpy.context.active_object
                ob.name = f"Canopy{k}_{j}"
                for vv in ob.data.vertices:  # lumpy foliage
                    vv.co *= 1.0 + 0.18 * (nrng.random() - 0.5)
                ob.data.materials.append(m_leaf[rng.randrange(3)])
                for c_ in ob.users_collection:
                    c_.objects.unlink(ob)
                coll.objects.link(ob)
            layout["trees"].append({"s": round(ss, 3), "side": side, "trunk_h": round(th, 3),
                                    "canopy_r": round(cr, 3), "base_world": [round(x, 3), round(y, 3), kerb]})
            k += 1
        s += rng.uniform(9, 14)
    # Signs: pole + plate with a generated face texture.
    sign_imgs = []
    for kind in range(4):
        n = 64
        yy, xx = np.mgrid[0:n, 0:n]
        r = np.hypot(xx - n / 2 + 0.5, yy - n / 2 + 0.5) / (n / 2)
        img = np.ones((n, n, 3)) * 0.9
        if kind == 0:  # blue circle with a white arrow
            img[r < 1] = (0.05, 0.2, 0.6)
            img[(np.abs(xx - n / 2) < 5) & (yy > 16) & (yy < 50)] = (0.95, 0.95, 0.95)
            img[(yy > 12) & (yy < 26) & (np.abs(xx - n / 2) < (yy - 12))] = (0.95, 0.95, 0.95)
        elif kind == 1:  # red ring, white centre, black bar
            img[r < 1] = (0.8, 0.05, 0.05)
            img[r < 0.78] = (0.95, 0.95, 0.95)
            img[(r < 0.78) & (np.abs(yy - n / 2) < 5) & (np.abs(xx - n / 2) < 18)] = (0.05, 0.05, 0.05)
        elif kind == 2:  # yellow diamond
            d = (np.abs(xx - n / 2) + np.abs(yy - n / 2)) / (n / 2)
            img[d < 1] = (0.05, 0.05, 0.05)
            img[d < 0.85] = (0.95, 0.75, 0.05)
        else:  # blue square "P"
            img[:] = (0.05, 0.25, 0.65)
            img[2:-2, 2:-2] = (0.08, 0.3, 0.7)
            img[12:52, 20:28] = 0.95
            img[12:36, 20:44] = np.where(((np.hypot(xx[12:36, 20:44] - 32, yy[12:36, 20:44] - 24) < 12) &
                                          (np.hypot(xx[12:36, 20:44] - 32, yy[12:36, 20:44] - 24) > 5))[:, :, None]
                                         | (xx[12:36, 20:44] < 28)[:, :, None], 0.95,
                                         img[12:36, 20:44])
        sign_imgs.append(textured(f"Sign{kind}", make_image(f"sign{kind}", img), rough=0.35))
    for i in range(10):
        ss = rng.uniform(s0 + 8, s1 - 8)
        side = 1 if rng.random() < 0.5 else -1
        x, y, h = road.at(ss, side * (road_w / 2 + 0.35))
        cylinder(f"SignPole{i}", 0.035, 2.7, 8, m_pole, (x, y, kerb), coll=coll)
        kind = rng.randrange(4)
        face = h + math.pi if rng.random() < 0.5 else h
        fxv, fyv = math.cos(face), math.sin(face)
        v = []
        for (a, b) in ((-0.35, -0.35), (0.35, -0.35), (0.35, 0.35), (-0.35, 0.35)):
            # plate in the plane spanned by the road-normal horizontal and up, facing along `face`
            v.append((x + fxv * 0.04 - fyv * a, y + fyv * 0.04 + fxv * a, kerb + 2.45 + b))
        mesh_object(f"SignPlate{i}", v + [(p[0] - fxv * 0.02, p[1] - fyv * 0.02, p[2]) for p in v],
                    [(0, 1, 2, 3), (7, 6, 5, 4)], [(0, 0), (1, 0), (1, 1), (0, 1)] * 2, [sign_imgs[kind]], coll=coll)
        layout["signs"].append({"s": round(ss, 3), "side": side, "kind": kind,
                                "center_world": [round(x, 3), round(y, 3), round(kerb + 2.45, 3)]})
    # Parked cars on the far (left) edge of the road: simple two-box shapes.
    m_rubber = principled("ParkedRubber", (0.03, 0.03, 0.03), rough=0.9)
    for i in range(4):
        ss = rng.uniform(s0 + 15, s1 - 15)
        x, y, h = road.at(ss, road_w / 2 - 1.05)
        cl = rng.uniform(3.8, 4.6)
        colr = [(0.6, 0.6, 0.62), (0.05, 0.05, 0.06), (0.5, 0.05, 0.05), (0.1, 0.2, 0.45), (0.85, 0.85, 0.85)][rng.randrange(5)]
        m = principled(f"ParkedPaint{i}", colr, rough=0.3, metal=0.6)
        box(f"Parked{i}", (cl, 1.75, 0.75), (x, y, 0.55), m, rot_z=h, coll=coll)
        ox, oy = math.cos(h) * -0.2, math.sin(h) * -0.2
        box(f"ParkedCab{i}", (cl * 0.5, 1.5, 0.55), (x + ox, y + oy, 1.2), principled(f"ParkedGlass{i}", (0.03, 0.03, 0.04), rough=0.05), rot_z=h, coll=coll)
        for wx in (-1, 1):
            for wy in (-1, 1):
                wx_, wy_ = wx * cl * 0.32, wy * 0.8
                px = x + math.cos(h) * wx_ - math.sin(h) * wy_
                py = y + math.sin(h) * wx_ + math.cos(h) * wy_
                # The cylinder's axis becomes the car's lateral axis; centre it on the wheel.
                w = cylinder(f"ParkedWheel{i}{wx}{wy}", 0.32, 0.2, 14, m_rubber, (px, py, 0.32), coll=coll)
                w.rotation_euler = (math.pi / 2, 0, h)
                w.location = (px - math.sin(h) * 0.1, py + math.cos(h) * 0.1, 0.32)
        layout["parked"].append({"s": round(ss, 3), "lateral": round(road_w / 2 - 1.05, 3), "length": round(cl, 3),
                                 "center_world": [round(x, 3), round(y, 3), 0.0]})
    # Bollards, bins and benches on the sidewalks.
    m_bin = principled("BinGreen", (0.08, 0.25, 0.12), rough=0.5)
    m_bench = principled("BenchWood", (0.45, 0.28, 0.14), rough=0.7)
    for i in range(8):
        ss = rng.uniform(s0 + 5, s1 - 5)
        side = 1 if rng.random() < 0.5 else -1
        x, y, h = road.at(ss, side * (road_w / 2 + side_w - 0.6))
        kind = rng.randrange(3)
        if kind == 0:
            cylinder(f"Bin{i}", 0.28, 0.95, 14, m_bin, (x, y, kerb), coll=coll)
        elif kind == 1:
            box(f"Bench{i}", (1.8, 0.5, 0.45), (x, y, kerb + 0.225), m_bench, rot_z=h, coll=coll)
        else:
            box(f"Cabinet{i}", (0.9, 0.45, 1.3), (x, y, kerb + 0.65), principled(f"Cab{i}", (0.5, 0.52, 0.5), rough=0.6),
                rot_z=h, coll=coll)
        layout["props"].append({"s": round(ss, 3), "side": side, "kind": ["bin", "bench", "cabinet"][kind],
                                "center_world": [round(x, 3), round(y, 3), kerb]})
    bs = zebra_s + rng.uniform(-8, -4)
    for i in range(9):
        x, y, h = road.at(bs + i * 1.4, -(road_w / 2 + 0.3))
        cylinder(f"Bollard{i}", 0.06, 0.9, 10, m_pole, (x, y, kerb), coll=coll)

    info = {"road": {"width_m": road_w, "lanes": 2, "lane_width_m": lane_w, "sidewalk_width_m": side_w,
                     "kerb_height_m": kerb, "street_extent_s_m": [s0, s1], "bend_start_s_m": road.bend_start,
                     "bend_length_m": road.bend_len, "bend_angle_deg": math.degrees(road.bend_angle),
                     "bend_ease_m": road.ease, "zebra_crossing_s": [zebra_s, zebra_s + 3.0],
                     "lateral_convention": "lateral offset l > 0 = left of the centreline (looking along +s)",
                     "centreline_polyline_xyz_s": [[round(float(np.interp(v, road.s, road.x)), 4),
                                                    round(float(np.interp(v, road.s, road.y)), 4), 0.0, v]
                                                   for v in np.arange(s0, s1 + 0.5, 1.0).tolist()]},
            "build_s": round(time.time() - t0, 2)}
    info.update(layout)
    return road, info


# ----------------------------------------------------------------------------------------------
# Sky and sun


def world_nodes(world, elev, rot, air, dust, ozone, strength):
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputWorld")
    skies = []
    for disc in (False, True):
        sky = nt.nodes.new("ShaderNodeTexSky")
        sky.sky_type = "NISHITA"
        sky.sun_disc = disc
        sky.sun_elevation = elev
        sky.sun_rotation = rot
        sky.air_density = air
        sky.dust_density = dust
        sky.ozone_density = ozone
        sky.altitude = 0.0
        skies.append(sky)
    bgs = []
    for sky in skies:
        bg = nt.nodes.new("ShaderNodeBackground")
        bg.inputs["Strength"].default_value = strength
        link(nt, sky.outputs["Color"], bg.inputs["Color"])
        bgs.append(bg)
    lp = nt.nodes.new("ShaderNodeLightPath")
    mix = nt.nodes.new("ShaderNodeMixShader")
    # Camera rays see the disc; every other ray sees the disc-less sky (the Sun lamp lights instead).
    link(nt, lp.outputs["Is Camera Ray"], mix.inputs["Fac"])
    link(nt, bgs[0].outputs["Background"], mix.inputs[1])
    link(nt, bgs[1].outputs["Background"], mix.inputs[2])
    link(nt, mix.outputs["Shader"], out.inputs["Surface"])
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = 1024
    return skies, bgs


def sun_direction(elev, rot):
    """World direction towards the sun for Nishita's (sun_elevation, sun_rotation): the rotation is
    measured clockwise from +Y, i.e. azimuth ccw from +X = pi/2 - rotation (checked by calibration)."""
    az = math.pi / 2 - rot
    return Vector((math.cos(elev) * math.cos(az), math.cos(elev) * math.sin(az), math.sin(elev)))


def render_calibration(scene, cam, skies, elev, rot, tmpdir):
    """Measures, at background strength 1: the sun disc's direction and irradiance, and the sky's
    irradiance on a horizontal surface. Renders only the world (a scene without geometry)."""
    r = scene.render
    scene.camera = cam
    res = {}
    # 1. An equirect of the sky: disc-on minus disc-off gives the disc centroid; disc-off gives E_sky.
    cam.data.type = "PANO"
    cam.data.cycles.panorama_type = "EQUIRECTANGULAR"
    cam.matrix_world = Matrix(((0, 0, -1, 0), (-1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 0, 1)))
    W, H = 2048, 1024
    r.resolution_x, r.resolution_y = W, H
    scene.cycles.samples = 4
    imgs = {}
    for disc in (False, True):
        skies[1].sun_disc = disc
        imgs[disc] = render_to_array(scene, os.path.join(tmpdir, f"cal_eq_{int(disc)}.exr"))
    skies[1].sun_disc = True
    rows = (np.arange(H) + 0.5) / H
    el = np.pi / 2 - np.pi * rows
    col = (np.arange(W) + 0.5) / W
    phi = np.pi * (1 - 2 * col)
    dome = imgs[False]
    omega = (2 * np.pi / W) * (np.sin(el + np.pi / (2 * H)) - np.sin(el - np.pi / (2 * H)))
    w_h = (omega * np.maximum(0, np.sin(el)))[:, None, None]
    res["E_sky_horizontal_rgb"] = (dome * w_h).sum(axis=(0, 1)).tolist()
    diff = (imgs[True] - imgs[False]).mean(axis=2)
    diff = np.where(diff > 0.05 * diff.max(), diff, 0.0) * omega[:, None]
    wsum = diff.sum()
    d = np.stack([np.cos(el)[:, None] * np.cos(phi)[None, :], np.cos(el)[:, None] * np.sin(phi)[None, :],
                  np.repeat(np.sin(el)[:, None], W, axis=1)], axis=2)
    cen = (d * diff[:, :, None]).sum(axis=(0, 1)) / wsum
    cen = Vector(cen.tolist()).normalized()
    formula = sun_direction(elev, rot)
    res["sun_dir_from_render"] = list(cen)
    res["sun_disc_centroid_offset_deg"] = math.degrees(cen.angle(formula))
    # 2. A narrow pinhole on the disc: disc-on minus disc-off, summed over solid angle = E_sun.
    cam.data.type = "PERSP"
    fov = math.radians(1.6)
    cam.data.sensor_fit = "HORIZONTAL"
    cam.data.angle = fov
    n = 96
    r.resolution_x = r.resolution_y = n
    cam.matrix_world = look_at(Vector((0, 0, 0)), formula, Vector((0, 0, 1)))
    scene.cycles.samples = 16
    for disc in (False, True):
        skies[1].sun_disc = disc
        imgs[disc] = render_to_array(scene, os.path.join(tmpdir, f"cal_sun_{int(disc)}.exr"))
    skies[1].sun_disc = True
    f_px = (n / 2) / math.tan(fov / 2)
    yy, xx = np.mgrid[0:n, 0:n]
    rx, ry = (xx + 0.5 - n / 2) / f_px, (yy + 0.5 - n / 2) / f_px
    om = (1.0 / f_px ** 2) / np.power(1 + rx * rx + ry * ry, 1.5)
    e_sun = ((imgs[True] - imgs[False]) * om[:, :, None]).sum(axis=(0, 1))
    res["E_sun_rgb"] = e_sun.tolist()
    res["sun_disc_peak_radiance"] = float(imgs[True].max())
    return res


def look_at(eye, target, up):
    """Blender camera matrix (looks along -Z, +Y up) at eye towards target."""
    f = (target - eye).normalized()
    r = f.cross(up).normalized()
    u = r.cross(f)
    m = Matrix(((r.x, u.x, -f.x, eye.x), (r.y, u.y, -f.y, eye.y), (r.z, u.z, -f.z, eye.z), (0, 0, 0, 1)))
    return m


def render_to_array(scene, path):
    """Renders the scene to a float EXR at path and returns it as a top-down HxWx3 array."""
    s = scene.render.image_settings
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"
    s.exr_codec = "ZIP"
    s.color_mode = "RGB"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True, scene=scene.name)
    return read_exr(path)


def read_exr(path):
    img = bpy.data.images.load(path, check_existing=False)
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return a.reshape(h, w, 4)[::-1, :, :3].copy()


def save_array(scene, arr, path, fmt, quality=90):
    """Writes a top-down HxWx3 linear array through Blender's own output path (so 8-bit files get
    exactly the render pipeline's view transform: Standard sRGB, exposure 0, no dither)."""
    h, w = arr.shape[:2]
    img = bpy.data.images.new("_tmp_out", w, h, alpha=False, float_buffer=True)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[:, :, :3] = arr[::-1]
    img.pixels.foreach_set(rgba.ravel())
    s = scene.render.image_settings
    if fmt == "EXR":
        # Half float (ZIP) is exact enough and a third smaller, but clips at 65504: frames whose
        # sun disc peaks above 65000 keep 32-bit float (PXR24: 24-bit mantissa, full range).
        half = float(arr.max()) < 65000.0
        s.file_format, s.color_mode = "OPEN_EXR", "RGB"
        s.color_depth, s.exr_codec = ("16", "ZIP") if half else ("32", "PXR24")
    elif fmt == "PNG":
        s.file_format, s.color_depth, s.compression, s.color_mode = "PNG", "8", 100, "RGB"
    img.save_render(path, scene=scene)
    bpy.data.images.remove(img)


# ----------------------------------------------------------------------------------------------
# Denoising the panoramas
#
# Debian's Blender has no OpenImageDenoise. The visible noise of a panorama at a few samples is
# visibility noise: shadowed facades and pavements see the sky, and the sunlit street, through a
# narrow gap, so few of a pixel's samples find it and the pixel is speckled; more samples reduce it
# only as their square root. In the shadowed facades of frame 1, the direct diffuse, indirect
# diffuse and indirect glossy light carry about a third of it each. Cycles' light passes hold the
# diffuse light as irradiance, the albedo apart (DiffCol), and the image is exactly
#     DiffCol (DiffDir + DiffInd) + GlossCol (GlossDir + GlossInd) + TransCol (TransDir + TransInd) + Emit + Env.
# The diffuse irradiance is filtered: an edge-avoiding a-trous filter (5x5 B3-spline taps at steps
# 1, 2, 4, 8 px), each tap weighted by the surfaces agreeing (normals, depth) and by the
# irradiance a 3x3 median sees there (its logarithm), so the sun's shadow edges, a factor of ~10 in
# irradiance, stay crisp and the speckles, outvoted by the median, are averaged away. Textures
# are untouched (the albedo multiplies the filtered irradiance back); reflections, glass and the
# sky keep their samples.

DENOISE_PASSES = ["DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd", "GlossCol", "TransDir", "TransInd",
                  "TransCol", "Emit", "Env", "Normal", "Depth", "Image"]


def setup_pass_output(scene, out_dir):
    """Enables the light passes and a compositor File Output node writing each as a float EXR."""
    vl = scene.view_layers[0]
    for attr in ("diffuse_direct", "diffuse_indirect", "diffuse_color", "glossy_direct", "glossy_indirect",
                 "glossy_color", "transmission_direct", "transmission_indirect", "transmission_color", "emit",
                 "environment", "normal", "z"):
        setattr(vl, "use_pass_" + attr, True)
    scene.use_nodes = True
    scene.render.use_compositing = True
    nt = scene.node_tree
    nt.nodes.clear()
    rl = nt.nodes.new("CompositorNodeRLayers")
    rl.scene, rl.layer = scene, vl.name
    comp = nt.nodes.new("CompositorNodeComposite")
    nt.links.new(rl.outputs["Image"], comp.inputs["Image"])
    fo = nt.nodes.new("CompositorNodeOutputFile")
    fo.base_path = out_dir
    fo.format.file_format, fo.format.color_depth, fo.format.exr_codec = "OPEN_EXR", "32", "ZIP"
    fo.format.color_mode = "RGB"
    fo.file_slots.clear()
    for name in DENOISE_PASSES:
        fo.file_slots.new(name)
        nt.links.new(rl.outputs[name], fo.inputs[name])
    return fo


def read_passes(out_dir, frame):
    return {n: read_exr(os.path.join(out_dir, f"{n}{frame:04d}.exr")) for n in DENOISE_PASSES}


def recombine(p, diffuse):
    """The image from its passes, with `diffuse` (DiffDir + DiffInd) as the diffuse irradiance."""
    return (p["DiffCol"] * diffuse + p["GlossCol"] * (p["GlossDir"] + p["GlossInd"]) +
            p["TransCol"] * (p["TransDir"] + p["TransInd"]) + p["Emit"] + p["Env"])


def padded(a, r):
    """a with r more pixels on every side: wrapped in longitude (an equirect image is periodic),
    the edge rows repeated at the poles. Views into it are the image shifted, without copies."""
    widths = ((r, r), (0, 0)) + ((0, 0),) * (a.ndim - 2)
    a = np.pad(a, widths, mode="edge")
    widths = ((0, 0), (r, r)) + ((0, 0),) * (a.ndim - 2)
    return np.pad(a, widths, mode="wrap")


def median3(a):
    h, w = a.shape
    p = padded(a, 1)
    return np.median(np.stack([p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1)]),
                     axis=0)


def denoise_diffuse(p, sigma_log=0.5, normal_power=64.0, depth_rel=0.03):
    """The panorama's diffuse irradiance (direct + indirect) filtered as the section above says."""
    irr = (p["DiffDir"] + p["DiffInd"]).astype(np.float32)
    h, w = irr.shape[:2]
    lum = irr @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    guide = np.log(median3(lum) + 1e-4).astype(np.float32)
    n = p["Normal"].astype(np.float32)
    z = p["Depth"][:, :, 0].astype(np.float32)
    surface = ((p["DiffCol"].max(axis=2) > 0) & (z < 1e5)).astype(np.float32)
    taps = np.array([1 / 16, 1 / 4, 3 / 8, 1 / 4, 1 / 16], np.float32)
    inv_sigma2 = np.float32(-0.5 / sigma_log ** 2)
    for step in (1, 2, 4, 8):
        r = 2 * step
        pi, pn, pz, pg, ps = padded(irr, r), padded(n, r), padded(z, r), padded(guide, r), padded(surface, r)
        acc = np.zeros_like(irr)
        wsum = np.zeros_like(z)
        for i, dy in enumerate(range(-2, 3)):
            for j, dx in enumerate(range(-2, 3)):
                ys, xs = slice(r + dy * step, r + dy * step + h), slice(r + dx * step, r + dx * step + w)
                if dy == 0 and dx == 0:
                    wt = np.full_like(z, taps[i] * taps[j])
                else:
                    cos_n = np.clip(np.einsum("ijk,ijk->ij", n, pn[ys, xs]), 1e-6, 1)
                    e = normal_power * np.log(cos_n)
                    e -= np.abs(pz[ys, xs] - z) / (depth_rel * step * max(abs(dy), abs(dx)) * z + 1e-6)
                    e += inv_sigma2 * (pg[ys, xs] - guide) ** 2
                    wt = taps[i] * taps[j] * np.exp(e) * ps[ys, xs]
                acc += wt[:, :, None] * pi[ys, xs]
                wsum += wt
        irr = np.where(surface[:, :, None] > 0, acc / np.maximum(wsum, 1e-12)[:, :, None], irr).astype(np.float32)
    return irr


# ----------------------------------------------------------------------------------------------
# Rig


def rig_model(args, rng):
    W, H = args.rig_w, args.rig_h
    hfov = 2 * math.pi / 3  # 120 deg edge to edge
    f = (W / 2) / (hfov / 2)
    cx, cy = (W - 1) / 2, (H - 1) / 2
    pixel_mm = 36.0 / max(W, H)
    radial = 0.075
    cams = []
    gains = [round(rng.uniform(0.84, 1.2), 4) for _ in range(6)]
    for c in range(6):
        yaw = math.radians(60 * c)
        dz = round(rng.uniform(-0.012, 0.012), 4)
        # OpenCV camera axes in rig coords: z (optical) = (cos yaw, sin yaw, 0), x (right) =
        # (sin yaw, -cos yaw, 0), y (down) = (0, 0, -1).
        zc = (math.cos(yaw), math.sin(yaw), 0.0)
        xc = (math.sin(yaw), -math.cos(yaw), 0.0)
        yc = (0.0, 0.0, -1.0)
        t = (radial * zc[0], radial * zc[1], dz)
        T = [[xc[0], yc[0], zc[0], t[0]], [xc[1], yc[1], zc[1], t[1]], [xc[2], yc[2], zc[2], t[2]], [0, 0, 0, 1]]
        T = [[round(v, 9) + 0.0 for v in row] for row in T]
        cams.append({"id": c, "name": f"cam{c}", "image_dir": f"rig/cam{c}", "model": "opencv_fisheye",
                     "width": W, "height": H, "fx": f, "fy": f, "cx": cx, "cy": cy,
                     "k1": 0.0, "k2": 0.0, "k3": 0.0, "k4": 0.0, "yaw_deg": 60 * c, "T_rig_cam": T,
                     "gain": gains[c], "exposure_ev": round(math.log2(gains[c]), 6)})
    corner = math.degrees(math.hypot(W / 2, H / 2) / f)
    rig = {
        "description": "6-camera fisheye rig. T_rig_cam maps OpenCV camera coordinates (x right, y down, z optical "
                       "axis) to rig coordinates (x forward, y left, z up). Equidistant fisheye: r_px = f * theta "
                       "(OpenCV fisheye/Kannala-Brandt with k1..k4 = 0). Pixel centres at integer coordinates "
                       "(OpenCV convention; image centre at ((W-1)/2, (H-1)/2)).",
        "rig_height_m": None,
        "camera_radial_offset_m": radial,
        "hfov_deg": 120.0,
        "vfov_deg": round(math.degrees(H / f), 4),
        "max_theta_deg_at_corners": round(corner, 4),
        "gains": gains,
        "cameras": cams,
        "blender": {"panorama_type": "FISHEYE_LENS_POLYNOMIAL", "sensor_fit": "AUTO (longer side = 36 mm)",
                    "sensor_mm": 36.0, "pixel_mm": pixel_mm, "f_mm": f * pixel_mm,
                    "fisheye_polynomial_k1": -1.0 / (f * pixel_mm),
                    "note": "Cycles computes theta = -(k0 + k1*r_mm + ...), r_mm measured from the image centre"},
    }
    return rig


OPENCV_TO_BLENDER_CAM = Matrix(((1, 0, 0, 0), (0, -1, 0, 0), (0, 0, -1, 0), (0, 0, 0, 1)))
# Equirect camera in the rig frame: image centre = +x_rig, columns grow towards -y_rig (right),
# up = +z_rig. Blender's panorama camera looks along its local -Z with +Y up.
RIG_TO_PANO_CAM = Matrix(((0, 0, -1, 0), (-1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 0, 1)))


def make_cameras(scene, rig, coll):
    cams = []
    for c in rig["cameras"]:
        cd = bpy.data.cameras.new(c["name"])
        cd.type = "PANO"
        cd.cycles.panorama_type = "FISHEYE_LENS_POLYNOMIAL"
        cd.sensor_fit = "AUTO"
        cd.sensor_width = 36.0
        cd.cycles.fisheye_polynomial_k0 = 0.0
        cd.cycles.fisheye_polynomial_k1 = rig["blender"]["fisheye_polynomial_k1"]
        cd.cycles.fisheye_polynomial_k2 = 0.0
        cd.cycles.fisheye_polynomial_k3 = 0.0
        cd.cycles.fisheye_polynomial_k4 = 0.0
        cd.cycles.fisheye_fov = 2 * math.pi  # Cycles drops rays beyond fov/2; the corners reach ~100 deg
        cd.clip_start = 0.01
        cd.clip_end = 1000
        ob = bpy.data.objects.new(c["name"], cd)
        coll.objects.link(ob)
        cams.append(ob)
    cd = bpy.data.cameras.new("pano")
    cd.type = "PANO"
    cd.cycles.panorama_type = "EQUIRECTANGULAR"
    cd.clip_start = 0.01
    cd.clip_end = 1000
    pano = bpy.data.objects.new("pano", cd)
    coll.objects.link(pano)
    return cams, pano


def rig_matrix(c):
    return Matrix([row for row in c["T_rig_cam"]])


def trajectory(args, road, rng, rig_height):
    n, fps = args.frames, args.fps
    ds = args.speed / fps
    s_start = road.bend_start - 2.0 - rng.uniform(0, 2)  # enter the bend during the clip
    lane = -road.lane_w / 2 if hasattr(road, "lane_w") else -1.9
    ph = [rng.uniform(0, 2 * math.pi) for _ in range(6)]
    frames = []
    for i in range(n):
        t = i / fps
        s = s_start + i * ds
        lat = lane + 0.12 * math.sin(0.9 * t + ph[0]) + 0.05 * math.sin(2.3 * t + ph[1])
        dlat = (0.12 * 0.9 * math.cos(0.9 * t + ph[0]) + 0.05 * 2.3 * math.cos(2.3 * t + ph[1])) / args.speed
        x, y, h = road.at(s, lat)
        yaw = h + math.atan(dlat) + math.radians(0.15) * math.sin(5.1 * t + ph[2])
        pitch = math.radians(0.6) * math.sin(3.7 * t + ph[3]) + math.radians(0.25) * math.sin(11.0 * t + ph[4])
        roll = math.radians(0.6) * math.sin(2.9 * t + ph[5]) + math.radians(0.2) * math.sin(9.0 * t + ph[2])
        R = (Matrix.Rotation(yaw, 4, "Z") @ Matrix.Rotation(pitch, 4, "Y") @ Matrix.Rotation(roll, 4, "X"))
        T = Matrix.Translation((x, y, rig_height)) @ R
        frames.append({"index": i, "timestamp": round(t, 6), "T": T, "s_m": s, "lateral_m": lat,
                       "yaw_deg": math.degrees(yaw), "pitch_deg": math.degrees(pitch), "roll_deg": math.degrees(roll)})
    return frames, lane


C_YUP = Matrix(((1, 0, 0, 0), (0, 0, 1, 0), (0, -1, 0, 0), (0, 0, 0, 1)))


def write_trajectory(out, frames, fps, rig_height, lane):
    js = {"frame_rate_hz": fps, "pose": "world_from_rig (4x4 row-major, maps rig coords to world)",
          "world": "Blender world: right-handed, Z up, metres",
          "world_yup": "world_yup_from_rig = C @ world_from_rig with C = [[1,0,0],[0,0,1],[0,-1,0]] "
                       "(glTF/three.js-style Y-up world; rig axes unchanged)",
          "rotation": "R = Rz(yaw) Ry(pitch) Rx(roll); pitch > 0 = nose down, roll > 0 = left side up",
          "rig_height_m": rig_height, "lane_offset_m": lane, "frames": []}
    lines = ["# timestamp tx ty tz qx qy qz qw  (world_from_rig, world = Blender Z-up, metres)"]
    for f in frames:
        T = f["T"]
        js["frames"].append({"index": f["index"], "timestamp": f["timestamp"], "world_from_rig": rounded(T),
                             "world_yup_from_rig": rounded(C_YUP @ T), "s_m": round(f["s_m"], 6),
                             "lateral_m": round(f["lateral_m"], 6), "yaw_deg": round(f["yaw_deg"], 6),
                             "pitch_deg": round(f["pitch_deg"], 6), "roll_deg": round(f["roll_deg"], 6)})
        q = T.to_quaternion()
        t = T.translation
        lines.append(f"{f['timestamp']:.6f} {t.x:.6f} {t.y:.6f} {t.z:.6f} {q.x:.9f} {q.y:.9f} {q.z:.9f} {q.w:.9f}")
    write_json(os.path.join(out, "trajectory_gt.json"), js)
    with open(os.path.join(out, "trajectory_gt.tum"), "w") as fh:
        fh.write("\n".join(lines) + "\n")


# ----------------------------------------------------------------------------------------------
# Render settings


def setup_cycles(scene, args):
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.use_denoising = False
    cy.use_adaptive_sampling = True
    cy.adaptive_threshold = args.adaptive_threshold
    cy.max_bounces = 3
    cy.diffuse_bounces = args.diffuse_bounces
    cy.glossy_bounces = 1
    cy.transmission_bounces = 1
    cy.transparent_max_bounces = 4
    cy.volume_bounces = 0
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = args.clamp_indirect
    cy.blur_glossy = 1.0
    cy.caustics_reflective = False
    cy.caustics_refractive = False
    cy.pixel_filter_type = "BLACKMAN_HARRIS"
    cy.filter_width = 1.5
    cy.use_animated_seed = False
    r = scene.render
    r.use_persistent_data = True
    r.resolution_percentage = 100
    r.dither_intensity = 0.0
    r.film_transparent = False
    if args.threads > 0:
        r.threads_mode = "FIXED"
        r.threads = args.threads
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.display_settings.display_device = "sRGB"


def render_frame_seed(seed, frame, cam):
    return (seed * 1000003 + frame * 101 + cam * 7 + 12345) % 2147483647


# ----------------------------------------------------------------------------------------------
# Verification of the conventions with emissive markers (no street)


def verify_conventions(args, rig, out, tmpdir):
    """Emissive markers at known rig-frame directions, seen by the panorama camera and the six
    fisheyes posed by an arbitrary rig pose; detected centroids vs the formulas of the README."""
    scene = bpy.data.scenes.new("Verify")
    setup_cycles(scene, args)
    scene.cycles.use_adaptive_sampling = False
    scene.world = bpy.data.worlds.new("black")
    scene.world.color = (0, 0, 0)
    coll = scene.collection
    T = Matrix.Translation((3.0, -2.0, 1.7)) @ Matrix.Rotation(0.4, 4, "Z") @ Matrix.Rotation(0.05, 4, "Y") @ \
        Matrix.Rotation(-0.03, 4, "X")
    dirs = []
    rng = random.Random(5)
    for i in range(14):
        az = rng.uniform(-math.pi, math.pi)
        el = rng.uniform(-0.9, 1.1)
        dirs.append(Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))))
    dist = 30.0
    em = bpy.data.materials.new("marker")
    em.use_nodes = True
    nt = em.node_tree
    nt.nodes.clear()
    o = nt.nodes.new("ShaderNodeOutputMaterial")
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Strength"].default_value = 1.0
    link(nt, e.outputs["Emission"], o.inputs["Surface"])
    for i, d in enumerate(dirs):
        me = bpy.data.meshes.new(f"mk{i}")
        ob = bpy.data.objects.new(f"mk{i}", me)
        bm = bmesh.new()
        bmesh.ops.create_uvsphere(bm, u_segments=24, v_segments=12, radius=0.3)
        bm.to_mesh(me)
        bm.free()
        me.materials.append(em)
        ob.location = T @ (d * dist)
        coll.objects.link(ob)
    cams, pano = make_cameras(scene, rig, coll)
    if args.denoise:
        setup_pass_output(scene, os.path.join(tmpdir, "passes"))
    result = {"markers": len(dirs)}
    # Panorama.
    W, H = 2048, 1024
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.cycles.samples = 16
    scene.camera = pano
    pano.matrix_world = T @ RIG_TO_PANO_CAM
    img = render_to_array(scene, os.path.join(tmpdir, "verify_pano.exr")).mean(axis=2)
    errs = []
    for d in dirs:
        phi = math.atan2(d.y, d.x)
        el = math.asin(d.z)
        u = (1 - phi / math.pi) * W / 2 - 0.5  # array index of the pixel whose centre looks along d
        v = (math.pi / 2 - el) / math.pi * H - 0.5
        # Intensity-weighted mean direction of the pixels around it (a pixel-space centroid would
        # be biased by the projection's stretch away from the equator), by the README's formula.
        r = 14
        x0, x1, y0, y1 = int(max(0, u - r)), int(min(W, u + r + 1)), int(max(0, v - r)), int(min(H, v + r + 1))
        patch = img[y0:y1, x0:x1]
        if patch.size == 0 or patch.max() < 0.3:
            continue
        yy, xx = np.mgrid[y0:y1, x0:x1]
        ph = np.pi * (1 - 2 * (xx + 0.5) / W)
        e = np.pi / 2 - np.pi * (yy + 0.5) / H
        m = np.stack([np.cos(e) * np.cos(ph), np.cos(e) * np.sin(ph), np.sin(e)], axis=2)
        c = Vector((m * patch[:, :, None]).sum(axis=(0, 1)).tolist()).normalized()
        errs.append(c.angle(d) / (2 * math.pi / W))  # in pixels at the equator
    result["equirect_marker_max_err_px"] = round(max(errs), 4) if errs else None
    result["equirect_markers_found"] = len(errs)
    # Fisheyes.
    scene.render.resolution_x, scene.render.resolution_y = args.rig_w, args.rig_h
    errs = []
    for c, ob in zip(rig["cameras"], cams):
        scene.camera = ob
        Trc = rig_matrix(c)
        ob.matrix_world = T @ Trc @ OPENCV_TO_BLENDER_CAM
        img = render_to_array(scene, os.path.join(tmpdir, f"verify_{c['name']}.exr")).mean(axis=2)
        inv = Trc.inverted()
        for d in dirs:
            p = inv @ (d * dist)  # marker in camera coords (the camera's own offset included)
            rxy = math.hypot(p.x, p.y)
            th = math.atan2(rxy, p.z)
            if th > math.radians(95):
                continue
            u = c["fx"] * th * p.x / rxy + c["cx"]
            v = c["fy"] * th * p.y / rxy + c["cy"]
            if not (6 < u < c["width"] - 7 and 6 < v < c["height"] - 7):
                continue
            cc = centroid(img, u, v, 8)  # array indices: pixel centres at integers, as OpenCV's
            if cc is not None:
                errs.append(math.hypot(cc[0] - u, cc[1] - v))
    result["fisheye_marker_max_err_px"] = round(max(errs), 4) if errs else None
    result["fisheye_marker_mean_err_px"] = round(sum(errs) / len(errs), 4) if errs else None
    result["fisheye_markers_found"] = len(errs)
    bpy.data.scenes.remove(scene)
    return result


def centroid(img, u, v, r):
    """Intensity centroid near (u, v), in array indices (the centre of pixel i is at i)."""
    h, w = img.shape
    x0, x1 = int(max(0, u - r)), int(min(w, u + r + 1))
    y0, y1 = int(max(0, v - r)), int(min(h, v + r + 1))
    patch = img[y0:y1, x0:x1]
    if patch.size == 0 or patch.max() < 0.3:
        return None
    yy, xx = np.mgrid[y0:y1, x0:x1]
    m = patch.sum()
    return float((xx * patch).sum() / m), float((yy * patch).sum() / m)


# ----------------------------------------------------------------------------------------------
# Main


def render_frame(scene, args, rig, cams, pano, f, out, tmpdir, v_dir):
    """Renders frame f: the six fisheyes (for the first --rig-frames frames), the panorama at the
    render size (the clip's frame), its committed 2x2 mean (rig frames) and EXR (--hdr-frames)."""
    i, T = f["index"], f["T"]
    t0 = time.time()
    scene.use_nodes = False  # the pass output is the panorama's alone
    if i < args.rig_frames:
        scene.render.resolution_x, scene.render.resolution_y = args.rig_w, args.rig_h
        scene.cycles.samples = args.spp
        s = scene.render.image_settings
        for c, ob in zip(rig["cameras"], cams):
            ob.matrix_world = T @ rig_matrix(c) @ OPENCV_TO_BLENDER_CAM
            scene.camera = ob
            scene.cycles.seed = render_frame_seed(args.seed, i, c["id"])
            scene.view_settings.exposure = math.log2(c["gain"])
            s.file_format, s.quality, s.color_mode = "JPEG", args.jpeg_quality, "RGB"
            scene.render.filepath = os.path.join(out, c["image_dir"], f"{i:06d}.jpg")
            bpy.ops.render.render(write_still=True, scene=scene.name)
        scene.view_settings.exposure = 0.0
    t1 = time.time()
    pano.matrix_world = T @ RIG_TO_PANO_CAM
    scene.camera = pano
    scene.render.resolution_x, scene.render.resolution_y = args.pr_w, args.pr_h
    scene.cycles.samples = args.pano_spp
    scene.cycles.seed = render_frame_seed(args.seed, i, 99)
    scene.use_nodes = args.denoise
    full = render_to_array(scene, os.path.join(tmpdir, "pano_full.exr"))
    extra = {}
    if args.denoise:
        t_d = time.time()
        passes = read_passes(os.path.join(tmpdir, "passes"), scene.frame_current)
        # The passes must add up to the image, or the filtered one would not be the render's.
        exact = recombine(passes, passes["DiffDir"] + passes["DiffInd"])
        extra["passes_vs_image_max_abs"] = round(float(np.abs(exact - passes["Image"]).max()), 6)
        full = recombine(passes, denoise_diffuse(passes))
        extra["denoise_s"] = round(time.time() - t_d, 2)
    save_array(scene, full, os.path.join(v_dir, f"{i:06d}.png"), "PNG")
    halve = (args.pr_w, args.pr_h) != (args.p_w, args.p_h)
    small = full.reshape(args.p_h, 2, args.p_w, 2, 3).mean(axis=(1, 3)) if halve else full
    if i < args.rig_frames:
        save_array(scene, small, os.path.join(out, "pano", f"{i:06d}.png"), "PNG")
    if i in args.hdr:
        save_array(scene, small, os.path.join(out, "pano_hdr", f"{i:06d}.exr"), "EXR")
    t2 = time.time()
    return dict({"frame": i, "rig_s": round(t1 - t0, 2), "pano_s": round(t2 - t1, 2), "total_s": round(t2 - t0, 2)}, **extra)


def main():
    args = parse_args()
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    tmpdir = os.path.join(out, "_work")
    os.makedirs(tmpdir, exist_ok=True)
    global TEX_DIR
    TEX_DIR = os.path.join(tmpdir, "tex")
    os.makedirs(TEX_DIR, exist_ok=True)
    t_all = time.time()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = "Street"
    setup_cycles(scene, args)
    rng = random.Random(args.seed)
    nrng = np.random.default_rng(args.seed)

    # The car first (its own RNG stream, so --car-only gives the same car).
    car_info = export_car(os.path.join(out, "car.glb"), random.Random(args.seed * 7919 + 1))
    if args.car_only:
        print("car.glb written", car_info)
        return

    rig = rig_model(args, rng)
    rig_height = round(rng.uniform(1.9, 2.2), 6)
    rig["rig_height_m"] = rig_height
    verify = None
    if args.verify:
        verify = verify_conventions(args, rig, out, tmpdir)
        print("VERIFY", verify)

    coll = bpy.data.collections.new("Street")
    scene.collection.children.link(coll)
    road, street = build_street(args, rng, nrng, coll)
    road.lane_w = street["road"]["lane_width_m"]
    frames, lane = trajectory(args, road, rng, rig_height)
    print(f"street built in {street['build_s']} s; {len(bpy.data.objects)} objects")

    # Sun: Nishita elevation / rotation, re-drawn until the disc is unoccluded from every rig position.
    deps = bpy.context.evaluated_depsgraph_get()
    mid = frames[len(frames) // 2]
    h_mid = math.radians(mid["yaw_deg"])
    draws = 0
    while True:
        draws += 1
        elev = math.radians(rng.uniform(28.0, 50.0))
        az = h_mid + math.radians(rng.uniform(-55.0, 55.0)) + (math.pi if rng.random() < 0.5 else 0.0)
        rot = math.pi / 2 - az
        d = sun_direction(elev, rot)
        vis = sum(1 for f in frames if not scene.ray_cast(deps, f["T"].translation, d)[0])
        if vis == len(frames) or draws > 60:
            break
    air, dust, ozone = 1.0, round(rng.uniform(0.5, 2.5), 4), 1.0
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    skies, bgs = world_nodes(world, elev, rot, air, dust, ozone, 1.0)

    # Calibrate the sun lamp against the disc and the exposure against a target irradiance.
    cal_scene = bpy.data.scenes.new("Calibration")
    setup_cycles(cal_scene, args)
    cal_scene.world = world
    cal_cam = bpy.data.objects.new("cal_cam", bpy.data.cameras.new("cal_cam"))
    cal_scene.collection.objects.link(cal_cam)
    cal = render_calibration(cal_scene, cal_cam, skies, elev, rot, tmpdir)
    bpy.data.scenes.remove(cal_scene)
    lum = np.array([0.2126, 0.7152, 0.0722])
    e_sun = np.array(cal["E_sun_rgb"])
    e_sky = np.array(cal["E_sky_horizontal_rgb"])
    e_h_target = 4.0
    e_h1 = float(lum @ (e_sun * math.sin(elev) + e_sky))
    k = e_h_target / e_h1
    for bg in bgs:
        bg.inputs["Strength"].default_value = k
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.angle = skies[1].sun_size
    e_scaled = e_sun * k
    sun.energy = float(e_scaled.max())
    sun.color = tuple((e_scaled / e_scaled.max()).tolist())
    sun_ob = bpy.data.objects.new("Sun", sun)
    sun_ob.matrix_world = look_at(Vector((0, 0, 0)), -sun_direction(elev, rot), Vector((0, 0, 1))) \
        if abs(sun_direction(elev, rot).z) < 0.999 else Matrix.Identity(4)
    scene.collection.objects.link(sun_ob)
    sun_info = {"elevation_deg": math.degrees(elev), "nishita_sun_rotation_rad": rot,
                "azimuth_deg_ccw_from_x": math.degrees(math.atan2(d.y, d.x)),
                "direction_world": rounded(list(d), 6), "dust_density": dust, "air_density": air,
                "ozone_density": ozone, "sun_size_deg": math.degrees(skies[1].sun_size),
                "background_strength": k, "sun_lamp_strength_W_m2": sun.energy, "sun_lamp_color": list(sun.color),
                "sun_lamp_angle_deg": math.degrees(sun.angle), "selection_draws": draws,
                "visible_from_fraction_of_rig_positions": vis / len(frames),
                "calibration": dict(cal, E_h_target=e_h_target, E_h_at_strength1=e_h1,
                                    sun_disc_peak_radiance_scaled=cal["sun_disc_peak_radiance"] * k)}
    print("SUN", json.dumps(sun_info)[:400])

    # Cameras and output folders.
    cams, pano = make_cameras(scene, rig, coll)
    if args.denoise:
        setup_pass_output(scene, os.path.join(tmpdir, "passes"))
    for c in rig["cameras"] if args.rig_frames > 0 else []:
        os.makedirs(os.path.join(out, c["image_dir"]), exist_ok=True)
    for d_ in ("pano", "pano_hdr") if args.rig_frames > 0 else ("pano_hdr",):
        os.makedirs(os.path.join(out, d_), exist_ok=True)
    v_dir = os.path.join(tmpdir, "pano_render")
    os.makedirs(v_dir, exist_ok=True)
    write_json(os.path.join(out, "rig.json"), rig)
    write_trajectory(out, frames, args.fps, rig_height, lane)

    # Each finished frame is recorded in _work/frames_done.json (atomically, after its files): with
    # --resume a rerun rebuilds the same scene and renders only the frames not recorded there.
    done_path = os.path.join(tmpdir, "frames_done.json")
    done = {}
    if args.resume and os.path.exists(done_path):
        with open(done_path) as fh:
            done = {int(k): v for k, v in json.load(fh).items()}
        print(f"resuming: {len(done)} of {len(frames)} frames already rendered", flush=True)
    only = args.only
    timings = []
    for f in frames:
        i = f["index"]
        if i not in done and i in only:
            done[i] = render_frame(scene, args, rig, cams, pano, f, out, tmpdir, v_dir)
            write_json(done_path, {str(k): v for k, v in sorted(done.items())})
            t = done[i]
            print(f"frame {i}: rig {t['rig_s']:.1f} s, pano {t['pano_s']:.1f} s", flush=True)
        if i in done:
            timings.append(done[i])
    if args.frame_range:
        print(f"frames {only.start}..{only.stop - 1} rendered into {tmpdir}", flush=True)
        return

    video = None
    if not args.no_video:
        video = os.path.join(out, "street.mp4")
        cmd = ["ffmpeg", "-y", "-loglevel", "error", "-framerate", str(args.fps), "-i",
               os.path.join(v_dir, "%06d.png"), "-c:v", "libx264", "-preset", "slow", "-crf", str(args.video_crf),
               "-pix_fmt", "yuv420p", "-movflags", "+faststart", video]
        subprocess.run(cmd, check=True)

    # Checks: PNG = sRGB(EXR) for the HDR frames, sun energy in the HDR panoramas, sizes.
    checks = {"hdr": []}
    for i in args.hdr:
        exr = read_exr(os.path.join(out, "pano_hdr", f"{i:06d}.exr"))
        png_path = os.path.join(out, "pano", f"{i:06d}.png")
        diff = None
        if os.path.exists(png_path):
            diff = float(np.abs(np.round(srgb_encode(exr) * 255) - np.round(read_png(png_path) * 255)).max())
        e_in = sun_energy(exr, frames[i]["T"], d, sun.angle)
        checks["hdr"].append({"frame": i, "exr_max": float(exr.max()),
                              "exr_pixel_type": "half (ZIP)" if exr.max() < 65000.0 else "float32 (PXR24)",
                              "png_vs_srgb_exr_max_abs_diff_8bit": diff,
                              "E_sun_in_exr_rgb": rounded(e_in.tolist(), 4),
                              "exr_over_lamp": round(float(lum @ e_in) / float(lum @ e_scaled), 4)})
    sizes = {}
    for name in ("rig", "pano", "pano_hdr"):
        sizes[name] = round(dir_size(os.path.join(out, name)) / 1e6, 3)
    for name in ("car.glb", "street.mp4"):
        p = os.path.join(out, name)
        if os.path.exists(p):
            sizes[name] = round(os.path.getsize(p) / 1e6, 3)
    checks["sizes_MB"] = sizes
    if verify:
        checks["verify"] = verify
    write_json(os.path.join(out, "checks.json"), checks)

    scene_js = {"seed": args.seed, "frames": args.frames,
                "world": "Blender world, right-handed, Z up, metres; road surface z = 0",
                "command": "blender -b --factory-startup --python tools/blender/make_street.py -- " +
                           " ".join(sys.argv[sys.argv.index("--") + 1:]),
                "sun": sun_info, "car": car_info}
    scene_js.update(street)
    scene_js["render"] = {"engine": "Cycles CPU (Blender %s)" % bpy.app.version_string, "spp": args.spp,
                          "pano_spp": args.pano_spp, "adaptive_sampling_threshold": args.adaptive_threshold, "max_bounces": 3,
                          "diffuse_bounces": args.diffuse_bounces, "glossy_bounces": 1, "transmission_bounces": 1, "clamp_indirect": args.clamp_indirect,
                          "filter": "Blackman-Harris 1.5 px",
                          "denoising": "diffuse irradiance, edge-avoiding a-trous (denoise_diffuse)" if args.denoise else False, "view_transform": "Standard",
                          "exposure": 0.0, "dither": 0.0, "rig_size": [args.rig_w, args.rig_h],
                          "pano_render_size": [args.pr_w, args.pr_h], "pano_size": [args.p_w, args.p_h],
                          "pano_downsample": "2x2 mean of the linear render" if (args.pr_w, args.pr_h) != (args.p_w, args.p_h) else "none",
                          "jpeg_quality": args.jpeg_quality, "hdr_frames": args.hdr,
                          "exr": "OpenEXR, linear scene-referred (no view transform): half float ZIP, or 32-bit "
                                 "float PXR24 where the sun disc peaks above 65000 (checks.json)"}
    scene_js["timings"] = {"per_frame": timings, "total_render_s": round(sum(t["total_s"] for t in timings), 1),
                           "total_script_s": round(time.time() - t_all, 1)}
    write_json(os.path.join(out, "scene.json"), scene_js)
    if not args.keep_work:
        shutil.rmtree(tmpdir, ignore_errors=True)
    print("done in %.1f s" % (time.time() - t_all))


def read_png(path):
    img = bpy.data.images.load(path, check_existing=False)
    w, h = img.size
    a = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(a)
    bpy.data.images.remove(img)
    return a.reshape(h, w, 4)[::-1, :, :3].copy()


def sun_energy(exr, T, d_world, angle):
    """Sun irradiance held by an HDR panorama: sum over a 3-degree cap around the sun of
    (L - the cap rim's median) times pixel solid angle."""
    H, W = exr.shape[:2]
    d = T.to_3x3().inverted() @ d_world
    el = np.pi / 2 - np.pi * (np.arange(H) + 0.5) / H
    phi = np.pi * (1 - 2 * (np.arange(W) + 0.5) / W)
    dirs = np.stack([np.cos(el)[:, None] * np.cos(phi)[None, :], np.cos(el)[:, None] * np.sin(phi)[None, :],
                     np.repeat(np.sin(el)[:, None], W, axis=1)], axis=2)
    cosang = dirs @ np.array(list(d))
    ang = np.degrees(np.arccos(np.clip(cosang, -1, 1)))
    cap = ang < 3.0
    rim = (ang >= 3.0) & (ang < 5.0)
    bg = np.median(exr[rim], axis=0)
    omega = (2 * np.pi / W) * (np.sin(el + np.pi / (2 * H)) - np.sin(el - np.pi / (2 * H)))
    om = np.repeat(omega[:, None], W, axis=1)
    return ((exr[cap] - bg) * om[cap][:, None]).sum(axis=0)


def dir_size(p):
    tot = 0
    for root, _, files in os.walk(p):
        for f in files:
            tot += os.path.getsize(os.path.join(root, f))
    return tot


if __name__ == "__main__":
    try:
        main()
    except Exception:
        import traceback
        traceback.print_exc()
        sys.exit(1)
