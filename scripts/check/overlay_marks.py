#!/usr/bin/env python3
"""Draws the book's hand-marked ground points (points2d.txt) on the renders of
graphs/book_scene.yaml, so one can check that the placed shadow catcher's corners A, B, C land
on them. Run after `vfxgraph run graphs/book_scene.yaml` from the repository root:

    python3 scripts/check/overlay_marks.py [catcher|full|desk]

Writes graphs/out/book_scene/marks.<kind>.png (the four marked frames, 2×2). Needs Pillow."""
import sys
from pathlib import Path

from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[2]
MARKS = ROOT / "../shared/data/book-demo/points2d.txt"
OUT = ROOT / "graphs/out/book_scene"


def read_marks(path):
    words = path.read_text().split()
    marks, i = {}, 0
    while i < len(words):
        if words[i] == "Frame":
            f, n = int(words[i + 1]), int(words[i + 3])
            marks[f] = [(float(words[i + 4 + 2 * k]), float(words[i + 5 + 2 * k])) for k in range(n)]
            i += 4 + 2 * n
        else:
            i += 1
    return marks


def main():
    kind = sys.argv[1] if len(sys.argv) > 1 else "catcher"
    marks = read_marks(MARKS)
    tiles = []
    for f in sorted(marks):
        im = Image.open(OUT / f"{kind}.{f:04d}.png").convert("RGB")
        s = im.width / 1280.0  # the video is 1280×720; pixel centres: x' + ½ = s(x + ½)
        d = ImageDraw.Draw(im)
        for k, (x, y) in enumerate(marks[f]):
            X, Y = s * (x + 0.5) - 0.5, s * (y + 0.5) - 0.5
            d.ellipse([X - 4, Y - 4, X + 4, Y + 4], outline=(255, 0, 0), width=2)
            d.text((X + 6, Y - 6), "ABCDEFGH"[k % 8], fill=(255, 0, 0))
        tiles.append(im)
    w, h = tiles[0].size
    sheet = Image.new("RGB", (2 * w, h * ((len(tiles) + 1) // 2)))
    for i, t in enumerate(tiles):
        sheet.paste(t, ((i % 2) * w, (i // 2) * h))
    out = OUT / f"marks.{kind}.png"
    sheet.save(out)
    print(out)


if __name__ == "__main__":
    main()
