#!/usr/bin/env python3
"""OpenImageIO's side of the image-format checks (crates/imaging/tests/oiio.rs).

    oiio_images.py write DIR   writes DPX files of every depth, packing, byte order and channel
                               count OpenImageIO writes, and TIFF files of 8/16-bit and float
                               samples, uncompressed, LZW and Deflate, 1/3/4 channels, each with `<name>.codes.f32` (the
                               codes it was given, over [0, 1], little-endian floats),
                               `<name>.f32` (OpenImageIO's own float read of it) and
                               `cases.json` (name → width, height, channels, bits)
    oiio_images.py read DIR    reads every `ours_*` image in DIR with OpenImageIO and writes
                               `<file>.f32` and `<file>.json` (size, channels, bits, transfer)
"""
import json
import os
import sys

import numpy as np
import OpenImageIO as oiio


def float_read(path):
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise SystemExit("OpenImageIO cannot open %s: %s" % (path, oiio.geterror()))
    spec = inp.spec()
    pixels = inp.read_image("float")
    inp.close()
    return spec, np.ascontiguousarray(pixels, dtype="<f4")


def write(dir_):
    rng = np.random.default_rng(7)
    cases = {}
    combos = []
    for bits in (8, 10, 12, 16):
        for packing in ("Packed", "Filled, method A", "Filled, method B"):
            for endian in ("big", "little"):
                combos.append((bits, packing, endian, 3))
    for bits in (8, 10, 16):
        for ch in (1, 4):
            combos.append((bits, "Filled, method A", "big", ch))
    for bits, packing, endian, ch in combos:
        w, h = 7, 3
        name = "oiio_%d_%s_%s_%d.dpx" % (bits, packing[-1], endian, ch)
        spec = oiio.ImageSpec(w, h, ch, "uint16" if bits > 8 else "uint8")
        spec.attribute("oiio:BitsPerSample", bits)
        spec.attribute("dpx:Packing", packing)
        spec.attribute("oiio:Endian", endian)
        spec.attribute("dpx:Transfer", "Printing density")
        codes = rng.integers(0, 2 ** bits, size=(h, w, ch))
        if bits > 8:
            pixels = (codes * 65535 // (2 ** bits - 1)).astype(np.uint16)
        else:
            pixels = codes.astype(np.uint8)
        path = os.path.join(dir_, name)
        out = oiio.ImageOutput.create(path)
        if not out.open(path, spec) or not out.write_image(pixels):
            raise SystemExit("OpenImageIO cannot write %s: %s" % (path, out.geterror()))
        out.close()
        (codes / (2 ** bits - 1)).astype("<f4").tofile(path + ".codes.f32")
        _, f = float_read(path)
        f.tofile(path + ".f32")
        cases[name] = {"width": w, "height": h, "channels": ch, "bits": bits}
    for fmt, bits in (("uint8", 8), ("uint16", 16), ("float", 32)):
        for compression in ("none", "lzw", "zip"):
            for ch in (1, 3, 4):
                w, h = 13, 5
                name = "oiio_%s_%s_%d.tif" % (fmt, compression, ch)
                spec = oiio.ImageSpec(w, h, ch, fmt)
                spec.attribute("compression", compression)
                if bits == 32:
                    values = rng.uniform(-0.5, 20.0, size=(h, w, ch)).astype("<f4")
                    pixels = values
                else:
                    codes = rng.integers(0, 2 ** bits, size=(h, w, ch))
                    values = codes / (2 ** bits - 1)
                    pixels = codes.astype(fmt)
                path = os.path.join(dir_, name)
                out = oiio.ImageOutput.create(path)
                if not out.open(path, spec) or not out.write_image(pixels):
                    raise SystemExit("OpenImageIO cannot write %s: %s" % (path, out.geterror()))
                out.close()
                np.asarray(values, dtype="<f4").tofile(path + ".codes.f32")
                _, f = float_read(path)
                f.tofile(path + ".f32")
                cases[name] = {"width": w, "height": h, "channels": ch, "bits": bits}
    # Photographs with a camera's focal length in EXIF: the focal plane's resolution (an APS-C
    # sensor 23.5 mm across at 600 px, a 35 mm lens), and a phone's 35 mm equivalent (26 mm).
    for name, (w, h), attrs in (
        ("camera.jpg", (600, 400), {"Exif:FocalLength": 35.0,
                                    "Exif:FocalPlaneXResolution": 600 / 2.35,
                                    "Exif:FocalPlaneYResolution": 600 / 2.35,
                                    "Exif:FocalPlaneResolutionUnit": 3}),
        ("phone.jpg", (400, 300), {"Exif:FocalLength": 4.2, "Exif:FocalLengthIn35mmFilm": 26}),
    ):
        spec = oiio.ImageSpec(w, h, 3, "uint8")
        for k, v in attrs.items():
            spec.attribute(k, v)
        path = os.path.join(dir_, name)
        out = oiio.ImageOutput.create(path)
        if not out.open(path, spec) or not out.write_image(np.zeros((h, w, 3), np.uint8)):
            raise SystemExit("OpenImageIO cannot write %s: %s" % (path, out.geterror()))
        out.close()
    with open(os.path.join(dir_, "cases.json"), "w") as fh:
        json.dump(cases, fh, indent=1)


def read(dir_):
    for name in sorted(os.listdir(dir_)):
        if not name.startswith("ours_") or name.endswith((".f32", ".json")):
            continue
        path = os.path.join(dir_, name)
        spec, f = float_read(path)
        f.tofile(path + ".f32")
        info = {
            "width": spec.width,
            "height": spec.height,
            "channels": spec.nchannels,
            "bits": spec.get_int_attribute("oiio:BitsPerSample", 0),
            "transfer": spec.get_string_attribute("dpx:Transfer", ""),
            "packing": spec.get_string_attribute("dpx:Packing", ""),
            "compression": spec.get_string_attribute("compression", ""),
        }
        with open(path + ".json", "w") as fh:
            json.dump(info, fh)


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("write", "read"):
        raise SystemExit(__doc__)
    {"write": write, "read": read}[sys.argv[1]](sys.argv[2])
