"""The speed-accuracy chart as a PNG, drawn with numpy and zlib (no plotting package among the
dependencies): accuracy against seconds per pair on a log axis, the Pareto front in red."""

from __future__ import annotations

import math
import struct
import zlib
from pathlib import Path

import numpy as np

# 5x7 glyphs: seven rows of 5 bits as hex pairs (bit 4 is the leftmost pixel)
_GLYPHS = {
    "A": "0E11111F111111",
    "B": "1E11111E11111E",
    "C": "0E11101010110E",
    "D": "1C12111111121C",
    "E": "1F10101E10101F",
    "F": "1F10101E101010",
    "G": "0E11101711110F",
    "H": "1111111F111111",
    "I": "0E04040404040E",
    "J": "0702020202120C",
    "K": "11121418141211",
    "L": "1010101010101F",
    "M": "111B1515111111",
    "N": "11111915131111",
    "O": "0E11111111110E",
    "P": "1E11111E101010",
    "Q": "0E11111115120D",
    "R": "1E11111E141211",
    "S": "0F10100E01011E",
    "T": "1F040404040404",
    "U": "1111111111110E",
    "V": "11111111110A04",
    "W": "1111111515150A",
    "X": "11110A040A1111",
    "Y": "11110A04040404",
    "Z": "1F01020408101F",
    "0": "0E11131519110E",
    "1": "040C040404040E",
    "2": "0E11010204081F",
    "3": "1F02040201110E",
    "4": "02060A121F0202",
    "5": "1F101E0101110E",
    "6": "0608101E11110E",
    "7": "1F010204080808",
    "8": "0E11110E11110E",
    "9": "0E11110F01020C",
    " ": "00000000000000",
    ".": "00000000000C0C",
    "-": "0000001F000000",
    "+": "0004041F040400",
    "%": "18190204081303",
    "(": "02040808080402",
    ")": "08040202020408",
    "/": "00010204081000",
    ":": "000C0C000C0C00",
    "=": "00001F001F0000",
}
WIDTH, HEIGHT = 1000, 640
LEFT, RIGHT, TOP, BOTTOM = 80, 30, 50, 70
BLACK, GREY, LIGHT, RED = (0, 0, 0), (120, 120, 120), (225, 225, 225), (210, 30, 30)
BLUE, ORANGE = (40, 90, 200), (230, 130, 20)


def pareto_front(points: dict[str, tuple[float, float | None]]) -> list[str]:
    """Names no other point beats on both axes (faster or as fast, and at least as accurate,
    strictly better on one), fastest first. Points without an accuracy are left out."""
    valid = {n: p for n, p in points.items() if p[1] is not None}

    def beaten(n: str) -> bool:
        t, a = valid[n]
        return any(
            (t2 <= t and a2 >= a) and (t2 < t or a2 > a) for m, (t2, a2) in valid.items() if m != n
        )

    return sorted((n for n in valid if not beaten(n)), key=lambda n: valid[n][0])


class Canvas:
    def __init__(self, width: int, height: int):
        self.pixels = np.full((height, width, 3), 255, dtype=np.uint8)

    def dot(self, x: float, y: float, radius: float, color) -> None:
        h, w, _ = self.pixels.shape
        yy, xx = np.ogrid[:h, :w]
        self.pixels[(xx - x) ** 2 + (yy - y) ** 2 <= radius**2] = color

    def ring(self, x: float, y: float, radius: float, color) -> None:
        h, w, _ = self.pixels.shape
        yy, xx = np.ogrid[:h, :w]
        d = np.sqrt((xx - x) ** 2 + (yy - y) ** 2)
        self.pixels[np.abs(d - radius) <= 1.0] = color

    def line(self, x0: float, y0: float, x1: float, y1: float, color, width: int = 1) -> None:
        steps = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
        for x, y in zip(np.linspace(x0, x1, steps), np.linspace(y0, y1, steps), strict=True):
            r = width // 2
            self.pixels[int(y) - r : int(y) + r + 1, int(x) - r : int(x) + r + 1] = color

    def text(self, x: int, y: int, text: str, color, scale: int = 1, vertical: bool = False):
        """Write upper-cased ``text`` with its top-left corner at (x, y); unknown characters
        print as spaces."""
        glyphs = [_GLYPHS.get(ch, _GLYPHS[" "]) for ch in text.upper()]
        bitmap = np.zeros((7, 6 * len(glyphs)), dtype=bool)
        for i, rows in enumerate(glyphs):
            for r in range(7):
                bits = int(rows[2 * r : 2 * r + 2], 16)
                bitmap[r, 6 * i : 6 * i + 5] = [(bits >> (4 - c)) & 1 for c in range(5)]
        bitmap = np.kron(bitmap, np.ones((scale, scale), dtype=bool))
        if vertical:
            bitmap = np.rot90(bitmap)
        h, w = bitmap.shape
        region = self.pixels[y : y + h, x : x + w]
        region[bitmap[: region.shape[0], : region.shape[1]]] = color

    def png(self) -> bytes:
        h, w, _ = self.pixels.shape
        raw = b"".join(b"\x00" + self.pixels[r].tobytes() for r in range(h))

        def chunk(kind: bytes, data: bytes) -> bytes:
            body = kind + data
            return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

        header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
        return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))  # fmt: skip


def _color(name: str):
    if name.startswith("DR-KFS torch"):
        return ORANGE
    return BLUE if name.startswith("DR-KFS") else GREY


def write_chart(
    path: Path, points: dict[str, tuple[float, float | None]], front: list[str]
) -> Path:
    """Accuracy (y) against seconds per pair (x, log), a labelled dot per method."""
    valid = {n: p for n, p in points.items() if p[1] is not None}
    canvas = Canvas(WIDTH, HEIGHT)
    times = [t for t, _ in valid.values()]
    lo, hi = math.floor(math.log10(min(times))), math.ceil(math.log10(max(times)))
    hi = max(hi, lo + 1)
    y_lo = math.floor(min(a for _, a in valid.values()) * 10 - 0.5) / 10
    y_lo = min(max(y_lo, 0.0), 0.9)
    x0, x1, y0, y1 = LEFT, WIDTH - RIGHT, HEIGHT - BOTTOM, TOP

    def xy(t: float, a: float) -> tuple[float, float]:
        x = x0 + (math.log10(t) - lo) / (hi - lo) * (x1 - x0)
        return x, y0 + (a - y_lo) / (1.0 - y_lo) * (y1 - y0)

    for decade in range(lo, hi + 1):
        x, _ = xy(10.0**decade, y_lo)
        canvas.line(x, y1, x, y0, LIGHT)
        canvas.text(int(x) - 12, y0 + 8, f"{10.0**decade:g}", BLACK)
    for tick in np.arange(y_lo, 1.0001, 0.1):
        _, y = xy(10.0**lo, tick)
        canvas.line(x0, y, x1, y, LIGHT)
        canvas.text(x0 - 30, int(y) - 3, f"{tick:.1f}", BLACK)
    canvas.line(x0, y0, x1, y0, BLACK)
    canvas.line(x0, y0, x0, y1, BLACK)
    canvas.text(x0 + 250, y0 + 35, "seconds per pair (log scale, 2 new meshes)", BLACK, 2)
    canvas.text(12, y1 + 120, "accuracy", BLACK, 2, vertical=True)
    canvas.text(x0, 15, "structural sensitivity vs speed   red: pareto front", BLACK, 2)
    for a, b in zip(front, front[1:], strict=False):
        canvas.line(*xy(*valid[a]), *xy(*valid[b]), RED, 2)
    placed: list[tuple[int, int, int, int]] = []
    for name, (t, a) in sorted(valid.items(), key=lambda item: item[1]):
        x, y = xy(t, a)
        canvas.dot(x, y, 5, _color(name))
        if name in front:
            canvas.ring(x, y, 8, RED)
        width = 6 * len(name)
        for dx, dy in ((10, -3), (10, -14), (10, 8), (-width - 10, -3), (-width - 10, 8)):
            box = (int(x) + dx, int(y) + dy, int(x) + dx + width, int(y) + dy + 7)
            if not any(_overlap(box, other) for other in placed):
                break
        placed.append(box)
        canvas.text(box[0], box[1], name, _color(name) if name not in front else RED)
    path.write_bytes(canvas.png())
    return path


def _overlap(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] + 2 and b[1] < a[3] + 2
