"""The speed-accuracy chart (matplotlib): accuracy against seconds per pair on a log axis, the
Pareto front joined, the presets marked."""

from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure

SIZE_INCHES, DPI = (10.0, 6.4), 110
COLORS = {"DR-KFS torch": "tab:orange", "DR-KFS": "tab:blue", "other": "tab:grey"}
FRONT_COLOR = "tab:red"


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


def _kind(name: str) -> str:
    if name.startswith("DR-KFS torch"):
        return "DR-KFS torch"
    return "DR-KFS" if name.startswith("DR-KFS") else "other"


def write_chart(
    path: Path,
    points: dict[str, tuple[float, float | None]],
    front: list[str],
    presets: dict[str, str] | None = None,
) -> Path:
    """points: method -> (seconds per pair, accuracy or None); front: ``pareto_front(points)``;
    presets: method -> a label to mark it with (the shipped default, the paper's recipe)."""
    presets = presets or {}
    valid = {n: p for n, p in points.items() if p[1] is not None}
    figure = Figure(figsize=SIZE_INCHES, dpi=DPI, layout="constrained")
    axes = figure.add_subplot()
    for kind, color in COLORS.items():
        names = [n for n in valid if _kind(n) == kind]
        if names:
            xs, ys = zip(*(valid[n] for n in names), strict=True)
            label = {"other": "other methods"}.get(kind, f"{kind} configs")
            axes.scatter(xs, ys, s=36, color=color, label=label, zorder=3)
    if front:
        xs, ys = zip(*(valid[n] for n in front), strict=True)
        axes.plot(xs, ys, color=FRONT_COLOR, lw=1.5, zorder=2, label="Pareto front")
        axes.scatter(xs, ys, s=140, facecolors="none", edgecolors=FRONT_COLOR, zorder=4)
    marked = [n for n in presets if n in valid]
    if marked:
        xs, ys = zip(*(valid[n] for n in marked), strict=True)
        axes.scatter(xs, ys, s=200, marker="*", color="black", zorder=5, label="presets")
    axes.set_xscale("log")
    axes.set_xlabel("seconds per pair (two new meshes, log scale)")
    axes.set_ylabel("accuracy: invisible changes scored below structural ones")
    axes.set_title("DR-KFS and its peers: ranking a missing part first, against speed")
    axes.grid(True, which="both", color="0.9")
    axes.margins(x=0.15, y=0.08)
    figure.legend(loc="outside lower center", ncols=5)
    figure.draw_without_rendering()  # fixes the layout, so label boxes can be placed in pixels
    _label(axes, valid, front, presets)
    figure.savefig(path)
    return path


def _label(axes, valid, front: list[str], presets: dict[str, str]) -> None:
    """Name every point, each label at the first of a few offsets where its box overlaps no
    label placed before it (boxes estimated from the font size, in display pixels)."""
    size = 7.5
    pixel = axes.figure.dpi / 72.0
    placed: list[tuple[float, float, float, float]] = []
    offsets = (
        (7, 4, "left"),
        (7, -11, "left"),
        (-7, 4, "right"),
        (-7, -11, "right"),
        (0, 10, "center"),
        (0, -18, "center"),
    )
    for name, (t, a) in sorted(valid.items(), key=lambda item: item[1]):
        mark = presets.get(name)
        text = f"{name} ({mark})" if mark and mark.split()[0] not in name else name
        x, y = axes.transData.transform((t, a))
        width, height = 0.55 * size * len(text) * pixel, size * pixel
        for dx, dy, align in offsets:
            left = x + dx * pixel - {"left": 0, "right": width, "center": width / 2}[align]
            box = (left, y + dy * pixel, left + width, y + dy * pixel + height)
            if not any(_overlap(box, other) for other in placed):
                break
        placed.append(box)
        axes.annotate(
            text, (t, a), xytext=(dx, dy), textcoords="offset points", ha=align, fontsize=size,
            color=FRONT_COLOR if name in front else "0.25",
            fontweight="bold" if name in presets else "normal",
        )  # fmt: skip


def _overlap(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]
