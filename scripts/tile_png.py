#!/usr/bin/env python3
"""Tiles PNG frames of one size into a grid, with the standard library only.

    scripts/tile_png.py COLUMNS OUT.png IN1.png IN2.png ...

Reads 8-bit RGB or RGBA PNGs (what sph-app writes), fills the grid row by
row and writes an RGBA PNG. README and BENCHMARKS strips are made with it.
"""

import struct
import sys
import zlib


def read_png(path):
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise SystemExit(f"{path}: not a PNG")
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
    width, height, depth, colour, _, _, interlace = header
    channels = {2: 3, 6: 4}.get(colour)
    if depth != 8 or channels is None or interlace:
        raise SystemExit(f"{path}: only 8-bit, non-interlaced RGB or RGBA")
    raw = zlib.decompress(idat)
    stride = width * channels
    rows, previous = [], bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        kind, line = raw[start], bytearray(raw[start + 1 : start + 1 + stride])
        for x in range(stride):
            a = line[x - channels] if x >= channels else 0
            b = previous[x]
            c = previous[x - channels] if x >= channels else 0
            if kind == 1:
                line[x] = (line[x] + a) & 255
            elif kind == 2:
                line[x] = (line[x] + b) & 255
            elif kind == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                predictor = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[x] = (line[x] + predictor) & 255
        rows.append(line)
        previous = line
    if channels == 3:
        rows = [
            bytearray(b for i in range(0, stride, 3) for b in (*row[i : i + 3], 255))
            for row in rows
        ]
    return width, height, rows


def write_png(path, width, height, rows):
    def chunk(kind, body):
        crc = zlib.crc32(kind + body) & 0xFFFFFFFF
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", crc)

    raw = b"".join(b"\x00" + bytes(row) for row in rows)
    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", header))
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


def main():
    if len(sys.argv) < 4:
        raise SystemExit(__doc__)
    columns, out, inputs = int(sys.argv[1]), sys.argv[2], sys.argv[3:]
    images = [read_png(p) for p in inputs]
    width, height = images[0][0], images[0][1]
    if any((w, h) != (width, height) for w, h, _ in images):
        raise SystemExit("the frames differ in size")
    grid_rows = -(-len(images) // columns)
    blank = bytearray(width * 4)
    rows = []
    for r in range(grid_rows):
        tiles = images[r * columns : (r + 1) * columns]
        for y in range(height):
            line = bytearray()
            for c in range(columns):
                line += tiles[c][2][y] if c < len(tiles) else blank
            rows.append(line)
    write_png(out, width * columns, height * grid_rows, rows)


if __name__ == "__main__":
    main()
