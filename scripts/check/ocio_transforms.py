#!/usr/bin/env python3
"""OpenColorIO's side of the colour-transform checks (crates/imaging/tests/ocio.rs).

    ocio_transforms.py [CONFIG]   prints JSON: for every listed colour space, a fixed set of
                                  RGB test values converted by PyOpenColorIO's CPU processor
                                  from that space to each working space and back, and through
                                  the display/view transforms the previews use

CONFIG defaults to the built-in studio config vfxgraph uses
(`ocio://studio-config-v4.0.0_aces-v2.0_ocio-v2.5`). The test values are fixed here, so the
Rust side applies its transforms to exactly these inputs and compares.
"""
import json
import sys

import PyOpenColorIO as ocio

CONFIG = "ocio://studio-config-v4.0.0_aces-v2.0_ocio-v2.5"

# The working spaces a graph states (scene-linear).
WORKING = ["ACEScg", "Linear Rec.709 (sRGB)"]

# The colour spaces files are read from and written to: encoded values in, scene-linear out.
SPACES = [
    "sRGB Encoded Rec.709 (sRGB)",
    "Camera Rec.709",
    "Linear Rec.709 (sRGB)",
    "ACES2065-1",
    "ACEScg",
    "ACEScct",
    "ARRI LogC3 (EI800)",
    "ARRI LogC4",
    "S-Log3 S-Gamut3.Cine",
    "Rec.1886 Rec.709 - Display",
    "Rec.2100-HLG - Display",
    "Rec.2100-PQ - Display",
]

# Spaces whose values are encodings (code values over about [0, 1]); the rest are linear.
LINEAR = {"Linear Rec.709 (sRGB)", "ACES2065-1", "ACEScg"}

# Display/view pairs the previews use, from scene-linear.
DISPLAY_VIEWS = [
    ("sRGB - Display", "ACES 2.0 - SDR 100 nits (Rec.709)"),
    ("sRGB - Display", "Un-tone-mapped"),
    ("sRGB - Display", "Video (colorimetric)"),
    ("Rec.1886 Rec.709 - Display", "ACES 2.0 - SDR 100 nits (Rec.709)"),
    ("Rec.2100-PQ - Display", "ACES 2.0 - HDR 1000 nits (P3 D65)"),
    ("Rec.2100-HLG - Display", "ACES 2.0 - HDR 1000 nits (P3 D65)"),
]

# Encoded values: negatives, near zero, the log curves' toes and cuts (LogC3's 0.092809,
# ACEScct's 0.155251, S-Log3's 171.21/1023), mid-tones, 1 and above.
ENCODED = [-0.1, -0.01, 0.0, 1e-5, 0.001, 0.01, 0.05, 0.092809, 0.1, 0.155251, 0.1673609,
           0.18, 0.25, 0.3, 0.391, 0.5, 0.6, 0.75, 0.9, 1.0, 1.1]
# Scene-linear values: negatives, near zero, the log curves' linear cuts (LogC3's 0.010591,
# ACEScct's 0.0078125), grey, highlights well above 1.
LINEAR_VALUES = [-0.05, -0.001, 0.0, 1e-6, 1e-4, 0.001, 0.0078125, 0.010591, 0.01, 0.05, 0.18,
                 0.5, 1.0, 2.0, 8.0, 16.0, 50.0, 100.0]


def triples(values):
    """Grey, and two coloured pixels per value (so gamut matrices mix channels)."""
    out = []
    for v in values:
        out.append([v, v, v])
        out.append([v, 0.6 * v + 0.02, 0.25 * v])
        out.append([0.1 * v, v, 0.5 * v + 0.01])
    return out


def apply(cpu, pixels):
    out = []
    for p in pixels:
        out.append([float(x) for x in cpu.applyRGB([float(x) for x in p])])
    return out


def main():
    name = sys.argv[1] if len(sys.argv) > 1 else CONFIG
    config = ocio.Config.CreateFromFile(name)
    cases = []
    for space in SPACES:
        encoded = triples(LINEAR_VALUES if space in LINEAR else ENCODED)
        linear = triples(LINEAR_VALUES)
        for work in WORKING:
            for src, dst, pixels in [(space, work, encoded), (work, space, linear)]:
                cpu = config.getProcessor(src, dst).getDefaultCPUProcessor()
                cases.append({"kind": "colour_space", "src": src, "dst": dst,
                              "input": pixels, "output": apply(cpu, pixels)})
    for work in WORKING:
        linear = triples(LINEAR_VALUES)
        for display, view in DISPLAY_VIEWS:
            t = ocio.DisplayViewTransform(src=work, display=display, view=view)
            cpu = config.getProcessor(t).getDefaultCPUProcessor()
            cases.append({"kind": "display_view", "src": work, "display": display,
                          "view": view, "input": linear, "output": apply(cpu, linear)})
    json.dump({"config": config.getName(), "ocio_version": ocio.__version__, "cases": cases},
              sys.stdout)


if __name__ == "__main__":
    main()
