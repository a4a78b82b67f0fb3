#!/usr/bin/env python3
"""Writes bricks.png, the height map of examples/scenes/features.rib's brick wall (read by the
heightmap shader through Option "searchpath" "string texture"). Only the standard library, so
the committed 64 x 64 PNG can be regenerated anywhere: python3 examples/textures/make_bricks.py"""
import os
import struct
import zlib

SIZE = 64         # pixels; the tile repeats (the shader reads it with "wrap" "periodic")
COURSE = 32       # pixels per course of bricks: two courses per tile
BRICK = 32        # pixels per brick along a course; alternate courses are offset by half
MORTAR = 1.5      # half width of a mortar joint, in pixels
BEVEL = 3.0       # pixels over which a brick's edge rises from the mortar to its face


def smoothstep(e0, e1, x):
    t = min(max((x - e0) / (e1 - e0), 0.0), 1.0)
    return t * t * (3 - 2 * t)


def height(x, y):
    course = int(y // COURSE)
    shift = BRICK // 2 if course % 2 else 0
    bx, by = (x + shift) % BRICK, y % COURSE
    # Distance to the nearest joint, measured from pixel centres so the tile wraps seamlessly.
    edge = min(bx + 0.5, BRICK - bx - 0.5, by + 0.5, COURSE - by - 0.5)
    brick = (course * 7 + (x + shift) // BRICK * 3) % 5  # a few bricks stand proud of the others
    face = 0.88 + 0.03 * brick
    return face * smoothstep(MORTAR, MORTAR + BEVEL, edge)


def write_png(path, rows):
    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))
    raw = b"".join(b"\0" + bytes(row) for row in rows)  # filter 0 on every scanline
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", SIZE, SIZE, 8, 0, 0, 0, 0)))  # 8-bit grey
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


rows = [[round(255 * height(x, y)) for x in range(SIZE)] for y in range(SIZE)]
write_png(os.path.join(os.path.dirname(os.path.abspath(__file__)), "bricks.png"), rows)
