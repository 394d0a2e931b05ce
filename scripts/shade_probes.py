#!/usr/bin/env python3
"""Writes the shader probes that `gpu_run.sh ... shade` times (VARIANTS=OUT_DIR): each a copy of
one file of shaders/ that leaves one part of the shading's work out, so that the time it saves
is that part's. They are probes, not pictures: their images are wrong by design.
  scripts/shade_probes.py OUT_DIR
"""
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent / "shaders"
# name: (file, the line it follows, the line put after it)
PROBES = {
    # the per-SG visible share replaced by the first cone's visibility
    "noshare": ("render_shade.comp", "float visibleShareOf(SgProduct prod, in ConeSet set, bool ground_loss) {",
                "  if (!ground_loss) return set.visibility[0];"),
    # no lighting SG from the overlap bins: the SG loops' whole cost
    "nosg": ("render_shade.comp", "  ivec2 range = overlapRange(lobe_axis, lobe_lambda);", "  range = ivec2(0);"),
    # the cones that meet the ground not traced on to its shadow
    "noground": ("render_shade.comp", "float groundLit(vec3 p, vec3 dir) {", "  return 1.0;"),
    # no cone traced; 0.75 keeps every visible-share path running
    "notrace": ("cone_trace.glsl", "float traceCone(vec3 o, vec3 dir, float alpha) {", "  if (alpha > -1.0) return 0.75;"),
}


def main() -> int:
    if len(sys.argv) != 2:
        print("usage: " + __doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    out = pathlib.Path(sys.argv[1])
    for name, (file, anchor, insert) in PROBES.items():
        text = (ROOT / file).read_text()
        if text.count(anchor + "\n") != 1:
            print(f"shade_probes.py: shaders/{file}: the line for probe {name} is not there once: {anchor}",
                  file=sys.stderr)
            return 1
        (out / name).mkdir(parents=True, exist_ok=True)
        (out / name / file).write_text(text.replace(anchor + "\n", anchor + "\n" + insert + "\n"))
    print(f"shade_probes.py: {len(PROBES)} probes in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
