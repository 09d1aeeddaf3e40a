#!/usr/bin/env python3
# view_png.py - pixel checks of the screenshots tests/browser.sh takes of frep view's page
# (standard library only: a PNG reader for 8-bit RGB/RGBA, zlib, the five filters).
#   view_png.py drawn SHOT.png SIDE   the model is drawn at the centre of the canvas (right
#                                     of a SIDE-pixel panel) and the legend's bar is there
#   view_png.py diff A.png B.png      the share of pixels that differ, for "it changed"
#   view_png.py same A.png B.png      every pixel equal, for "the same picture"
#   view_png.py colours SHOT.png X0 CHANNEL... at least 1% of the pixels right of x = X0
#                                     are of each CHANNEL (red, green, blue): that
#                                     channel at least 100 and twice each other one
import struct
import sys
import zlib

BACKGROUND = (237, 240, 247)   # gl.clearColor(0.93, 0.94, 0.97) of view/viewer.html


def read(path):
    d = open(path, 'rb').read()
    if d[:8] != b'\x89PNG\r\n\x1a\n':
        raise SystemExit(path + ': not a PNG')
    pos, idat, w, h, ctype = 8, b'', 0, 0, 2
    while pos < len(d):
        n, = struct.unpack('>I', d[pos:pos + 4])
        t, body = d[pos + 4:pos + 8], d[pos + 8:pos + 8 + n]
        pos += 12 + n
        if t == b'IHDR':
            w, h = struct.unpack('>II', body[:8])
            ctype = body[9]
        elif t == b'IDAT':
            idat += body
    bpp = 4 if ctype == 6 else 3
    raw, stride, prev, rows = zlib.decompress(idat), bpp * w, bytearray(bpp * w), []
    for y in range(h):
        ft = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if ft == 1:
                line[i] = (line[i] + a) & 255
            elif ft == 2:
                line[i] = (line[i] + b) & 255
            elif ft == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif ft == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(line)
        prev = line
    return w, h, bpp, rows


def px(img, x, y):
    w, h, bpp, rows = img
    return tuple(rows[y][bpp * x:bpp * x + 3])


def drawn(path, side):
    img = read(path)
    w, h = img[0], img[1]
    cx, cy = (side + w) // 2, h // 2
    hw, hh = (w - side) // 12, h // 12
    n = fg = 0
    for y in range(cy - hh, cy + hh, 2):
        for x in range(cx - hw, cx + hw, 2):
            n += 1
            fg += max(abs(a - b) for a, b in zip(px(img, x, y), BACKGROUND)) > 12
    bar = legend_bar(img)
    print('centre %.0f%% drawn, legend bar %s' % (100.0 * fg / n, 'found at y=%d' % bar if bar else 'missing'))
    return fg > 0.6 * n and bar is not None


def near(p, q, tol=8):
    return max(abs(a - b) for a, b in zip(p, q)) <= tol


def legend_bar(img):
    """A row of the bottom 200 pixels that runs from colour(0) to colour(1) over at
    least 100 pixels without touching the background: the legend's colour bar."""
    w, h = img[0], img[1]
    lo, hi = (25, 77, 255), (255, 0, 13)   # colour(0), colour(1) of view/viewer.html
    for y in range(max(0, h - 200), h):
        start = None
        for x in range(w):
            p = px(img, x, y)
            if near(p, lo):
                start = x if start is None else start
            elif start is not None and near(p, hi) and x - start >= 100:
                return y
            elif start is not None and near(p, BACKGROUND, 3):
                start = None
    return None


def diff(a_path, b_path):
    a, b = read(a_path), read(b_path)
    if a[:2] != b[:2]:
        print('sizes differ')
        return True
    n = d = 0
    for y in range(0, a[1], 2):
        for x in range(0, a[0], 2):
            n += 1
            d += px(a, x, y) != px(b, x, y)
    print('%.1f%% of the pixels differ' % (100.0 * d / n))
    return d > 0.02 * n


def same(a_path, b_path):
    a, b = read(a_path), read(b_path)
    if a[:2] != b[:2]:
        print('sizes differ')
        return False
    d = sum(px(a, x, y) != px(b, x, y) for y in range(a[1]) for x in range(a[0]))
    print('%d pixels differ' % d)
    return d == 0


CHANNELS = {'red': 0, 'green': 1, 'blue': 2}


def colours(path, x0, names):
    """Shaded surfaces of a pure colour keep its channel dominant (light only scales
    it; the highlight adds white to few pixels): count the pixels of each."""
    img = read(path)
    w, h = img[0], img[1]
    n, count = 0, {c: 0 for c in names}
    for y in range(0, h, 2):
        for x in range(x0, w, 2):
            n += 1
            p = px(img, x, y)
            for c in names:
                k = CHANNELS[c]
                if p[k] >= 100 and all(2 * p[j] <= p[k] for j in range(3) if j != k):
                    count[c] += 1
    print(', '.join('%s %.1f%%' % (c, 100.0 * count[c] / n) for c in names))
    return all(count[c] >= 0.01 * n for c in names)


if __name__ == '__main__':
    if sys.argv[1] == 'colours':
        sys.exit(0 if colours(sys.argv[2], int(sys.argv[3]), sys.argv[4:]) else 1)
    if sys.argv[1] == 'drawn':
        sys.exit(0 if drawn(sys.argv[2], int(sys.argv[3])) else 1)
    if sys.argv[1] == 'same':
        sys.exit(0 if same(sys.argv[2], sys.argv[3]) else 1)
    sys.exit(0 if diff(sys.argv[2], sys.argv[3]) else 1)
