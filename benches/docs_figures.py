"""Copy a comparison's figures into docs/figures/ small enough to commit (PNG <= 300 kB each).
Usage: python benches/docs_figures.py COMPARE_DIR [OUT_DIR] (`make figures` runs it on test1, seed 0)

Writes OUT_DIR/test1_image.png (SAR-MIN's quicklook) and OUT_DIR/test1_compare.png (compare.png), each
scaled to at most 1400 px wide and stored as a 128-colour palette PNG; a figure still over the limit is
scaled down further until it fits.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from PIL import Image

LIMIT_BYTES = 300_000
FIGURES = {"test1_image.png": Path("sar-min") / "image.png", "test1_compare.png": Path("compare.png")}


def shrink(src: Path, dst: Path, width: int = 1400) -> int:
    """Write ``src`` as a palette PNG of at most ``width`` px (smaller if needed for LIMIT_BYTES); its size."""
    image = Image.open(src).convert("RGB")
    while True:
        scaled = image if image.width <= width else image.resize(
            (width, round(image.height * width / image.width)), Image.Resampling.LANCZOS)
        scaled.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(dst, optimize=True)
        size = dst.stat().st_size
        if size <= LIMIT_BYTES:
            return size
        width = int(width * 0.85)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("compare_dir", type=Path)
    default_out = Path(__file__).resolve().parents[1] / "docs" / "figures"
    parser.add_argument("out_dir", type=Path, nargs="?", default=default_out)
    args = parser.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    for name, rel in FIGURES.items():
        size = shrink(args.compare_dir / rel, args.out_dir / name)
        print(f"wrote {args.out_dir / name} ({size / 1000:.0f} kB)")


if __name__ == "__main__":
    main()
