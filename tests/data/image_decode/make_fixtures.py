#!/usr/bin/python3
"""Writes the PNG and JPEG files of tests/vision/image_decode_test.cc.

  /usr/bin/python3 tests/data/image_decode/make_fixtures.py

Every PNG colour type and bit depth, with and without tRNS, Adam7
interlacing and ancillary chunks (gAMA, cHRM, sRGB, a bogus iCCP, pHYs, tEXt,
zTXt, tIME, eXIf), written by the small PNG writer below (zlib only, so
independent of libpng); JPEGs written with Pillow (libjpeg): grey and colour,
baseline and progressive, 4:2:0, 4:2:2 and 4:4:4, CMYK (restart markers:
the test encodes them with OpenCV). The images are 37 x 23 pixels (not a
multiple of any MCU) and their samples follow the formulas the test checks:
  grey(x, y) = (7 x + 11 y) mod 256, red = grey, green = (255 - 5 x) mod 256,
  blue = (3 y + 100) mod 256; 16-bit samples are v * 257 + x (mod 65536);
  alpha = (x * 9) mod 256. The files are committed; this script documents
where each came from and remakes them.
"""
import io
import os
import struct
import zlib

from PIL import Image

W, H = 37, 23
HERE = os.path.dirname(os.path.abspath(__file__))


def grey(x, y):
    return (7 * x + 11 * y) % 256


def green(x, y):
    return (255 - 5 * x) % 256


def blue(x, y):
    return (3 * y + 100) % 256


def alpha(x, y):
    return (x * 9) % 256


def wide(v, x):
    return (v * 257 + x) % 65536


def chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def pack_row(samples, depth):
    """Samples of one row (already flattened per pixel) packed at `depth` bits."""
    if depth == 8:
        return bytes(samples)
    if depth == 16:
        return b"".join(struct.pack(">H", s) for s in samples)
    out, acc, bits = bytearray(), 0, 0
    for s in samples:
        acc = (acc << depth) | s
        bits += depth
        if bits == 8:
            out.append(acc)
            acc, bits = 0, 0
    if bits:
        out.append(acc << (8 - bits))
    return bytes(out)


ADAM7 = [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]


def png(color_type, depth, pixel, interlace=False, extra_before=b"", extra_after=b"", plte=b""):
    """pixel(x, y) -> tuple of samples; rows filtered with filter 0 (None)."""
    raw = bytearray()
    passes = ADAM7 if interlace else [(0, 0, 1, 1)]
    for x0, y0, dx, dy in passes:
        xs = list(range(x0, W, dx))
        if not xs:
            continue
        for y in range(y0, H, dy):
            samples = [s for x in xs for s in pixel(x, y)]
            raw += b"\0" + pack_row(samples, depth)
    ihdr = struct.pack(">IIBBBBB", W, H, depth, color_type, 0, 0, 1 if interlace else 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + extra_before + plte +
            chunk(b"IDAT", zlib.compress(bytes(raw), 9)) + extra_after + chunk(b"IEND", b""))


def write(name, data):
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)


def main():
    g = lambda x, y: (grey(x, y),)
    rgb = lambda x, y: (grey(x, y), green(x, y), blue(x, y))
    write("grey8.png", png(0, 8, g))
    write("grey1.png", png(0, 1, lambda x, y: (grey(x, y) >> 7,)))
    write("grey2.png", png(0, 2, lambda x, y: (grey(x, y) >> 6,)))
    write("grey4.png", png(0, 4, lambda x, y: (grey(x, y) >> 4,)))
    write("grey16.png", png(0, 16, lambda x, y: (wide(grey(x, y), x),)))
    write("grey8_trns.png", png(0, 8, g, extra_before=chunk(b"tRNS", struct.pack(">H", 77))))
    write("grey_alpha8.png", png(4, 8, lambda x, y: (grey(x, y), alpha(x, y))))
    write("grey_alpha16.png", png(4, 16, lambda x, y: (wide(grey(x, y), x), wide(alpha(x, y), 0))))
    write("rgb8.png", png(2, 8, rgb))
    write("rgb8_trns.png", png(2, 8, rgb, extra_before=chunk(b"tRNS", struct.pack(">HHH", 0, 255, 100))))
    write("rgb16.png", png(2, 16, lambda x, y: tuple(wide(v, x) for v in rgb(x, y))))
    write("rgba8.png", png(6, 8, lambda x, y: rgb(x, y) + (alpha(x, y),)))
    write("rgba16.png", png(6, 16, lambda x, y: tuple(wide(v, x) for v in rgb(x, y) + (alpha(x, y),))))
    # Palette: 64 entries (x + y) mod 64 -> a colour; with tRNS for 40 of them.
    entry = lambda i: (i * 4, 255 - i * 3, (i * 37) % 256)
    plte = chunk(b"PLTE", b"".join(bytes(entry(i)) for i in range(64)))
    index = lambda x, y: ((x + y) % 64,)
    write("palette8.png", png(3, 8, index, plte=plte))
    write("palette8_trns.png", png(3, 8, index, plte=plte + chunk(b"tRNS", bytes(range(0, 240, 6)))))
    plte16 = chunk(b"PLTE", b"".join(bytes(entry(i * 4)) for i in range(16)))
    write("palette4.png", png(3, 4, lambda x, y: ((x + y) % 16,), plte=plte16))
    write("rgb8_interlaced.png", png(2, 8, rgb, interlace=True))
    write("grey16_interlaced.png", png(0, 16, lambda x, y: (wide(grey(x, y), x),), interlace=True))
    write("palette8_trns_interlaced.png",
          png(3, 8, index, interlace=True, plte=plte + chunk(b"tRNS", bytes(range(0, 240, 6)))))
    # Ancillary chunks OpenCV does not apply (gamma, colour space, profile,
    # text, time, EXIF orientation 6): the pixels stay the file's samples.
    exif = (b"MM\0*\0\0\0\x08\0\x01" + struct.pack(">HHII", 0x0112, 3, 1, 6 << 16) + b"\0\0\0\0")
    ancillary = (chunk(b"gAMA", struct.pack(">I", 45455)) +
                 chunk(b"cHRM", struct.pack(">8I", 31270, 32900, 64000, 33000, 30000, 60000, 15000, 6000)) +
                 chunk(b"sRGB", b"\0") +
                 chunk(b"iCCP", b"bogus\0\0" + zlib.compress(b"not an ICC profile")) +
                 chunk(b"pHYs", struct.pack(">IIB", 3780, 3780, 1)) +
                 chunk(b"tEXt", b"Comment\0made by make_fixtures.py") +
                 chunk(b"zTXt", b"Software\0\0" + zlib.compress(b"make_fixtures.py")) +
                 chunk(b"tIME", struct.pack(">HBBBBB", 2026, 12, 3, 9, 0, 0)) +
                 chunk(b"eXIf", exif))
    write("rgb8_ancillary.png", png(2, 8, rgb, extra_before=ancillary))
    write("grey8_ancillary.png", png(0, 8, g, extra_before=ancillary, extra_after=chunk(b"tEXt", b"After\0IDAT")))

    grey_image = Image.new("L", (W, H))
    grey_image.putdata([grey(x, y) for y in range(H) for x in range(W)])
    rgb_image = Image.new("RGB", (W, H))
    rgb_image.putdata([rgb(x, y) for y in range(H) for x in range(W)])

    def jpeg(image, **options):
        out = io.BytesIO()
        image.save(out, "JPEG", **options)
        return out.getvalue()

    write("grey.jpg", jpeg(grey_image, quality=90))
    write("grey_progressive.jpg", jpeg(grey_image, quality=90, progressive=True))
    write("rgb_420.jpg", jpeg(rgb_image, quality=85, subsampling=2))
    write("rgb_422.jpg", jpeg(rgb_image, quality=85, subsampling=1))
    write("rgb_444.jpg", jpeg(rgb_image, quality=95, subsampling=0))
    write("rgb_420_progressive.jpg", jpeg(rgb_image, quality=85, subsampling=2, progressive=True))
    write("rgb_444_progressive.jpg", jpeg(rgb_image, quality=95, subsampling=0, progressive=True))
    write("cmyk.jpg", jpeg(rgb_image.convert("CMYK"), quality=95))


if __name__ == "__main__":
    main()
