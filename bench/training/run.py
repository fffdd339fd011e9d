"""``drkfs train``: synthetic data -> detector sweep -> HardNet width sweep -> held-out evaluation
-> shipped weights and manifest. Every stage checkpoints to a work folder and resumes from it."""

from __future__ import annotations

import hashlib
import json
import math
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
import typer
from torch import nn

from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.contract.model_files import MANIFEST, sha256
from drkfs_onnx.metric import DRKFS, with_nets
from drkfs_onnx.nets.detector import PoIDetector
from drkfs_onnx.nets.hardnet import HardNet
from drkfs_onnx.synthetic.shapes import FAMILIES

from .data import ViewPairs, render_pairs, sample_matches
from .metric_stage import (
    ACCURACY_TOLERANCE,
    BASELINE,
    PLAN_DETECTOR,
    RETRIEVAL,
    Correspondences,
    MetricPlan,
    MetricStage,
    admissible,
    choose_objective,
    choose_smallest,
)
from .net_losses import correspondence_triplet, detector_loss
from .net_metrics import (
    conv_flops,
    descriptor_fpr95,
    difference_of_gaussians,
    harris,
    repeatability,
)

BORDER = 20  # matches stay this far inside the image: 16 for a 32-pixel patch, plus JITTER
FPR95_TOLERANCE = 1.0  # ship the smallest net within this many FPR95 points of the best
REPEAT_TOLERANCE = 0.01  # and the smallest detector within this repeatability of the best


@dataclass(frozen=True)
class TrainPlan:
    """Everything that decides the shipped weights, besides the code."""

    seed: int = 0
    shapes_per_family: int = 16
    pairs_per_shape: int = 4
    heldout_shapes_per_family: int = 4
    heldout_pairs_per_shape: int = 2
    matches_per_pair: int = 256
    detector_sizes: tuple[tuple[int, int, int], ...] = ((4, 4, 9), (2, 2, 9), (4, 4, 5))
    detector_steps: int = 250
    detector_batch: int = 8
    detector_lr: float = 1e-2
    widths: tuple[float, ...] = (1.0, 0.5, 0.25)
    hardnet_steps: int = 500
    hardnet_batch: int = 256
    hardnet_lr: float = 1e-3
    checkpoint_every: int = 50
    # the config the correspondence nets are trained at: the paper's cameras and image size. Its
    # detector fields are placeholders (the sweep sets each size), at the values the shipped run
    # recorded, so that its plan and work folder stay those of models/manifest.json.
    config: dict = field(default_factory=lambda: PipelineConfig.paper(**PLAN_DETECTOR).to_dict())
    # the second stage: the same nets fine-tuned for the metric, at the default config
    metric: MetricPlan = field(default_factory=MetricPlan)

    @property
    def pipeline(self) -> PipelineConfig:
        return PipelineConfig.from_dict(self.config)


QUICK_TRAIN = TrainPlan(
    shapes_per_family=1,
    pairs_per_shape=2,
    heldout_shapes_per_family=1,
    heldout_pairs_per_shape=1,
    matches_per_pair=64,
    detector_sizes=((4, 4, 9), (2, 2, 5)),
    detector_steps=6,
    detector_batch=4,
    widths=(0.25, 0.125),
    hardnet_steps=6,
    hardnet_batch=32,
    checkpoint_every=3,
    config=PipelineConfig(
        num_views=4, turn_degrees=0.0, image_size=128, nets="correspondence"
    ).to_dict(),
    metric=MetricPlan(
        shapes_per_family=2,
        objectives=("ranking", "patch contrast"),
        objective_width=0.25,
        steps=2,
        quick_benchmark=True,
        config=PipelineConfig.structure(
            nets="metric", num_views=2, turn_degrees=0.0, image_size=64
        ).to_dict(),
    ),
)


def plan_key(plan) -> str:
    """A short hash of a plan (a dataclass): checkpoints of different plans never mix in one
    work folder. A TrainPlan's key leaves out its metric stage, which keys its own subfolder,
    so a change there does not retrain the correspondence stage."""
    fields = asdict(plan)
    fields.pop("metric", None)
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:12]


def git_commit() -> str:
    """The commit of the repository this lab lives in (not the working folder's), with "-dirty"
    where tracked files differ from it; "unknown" outside a repository."""
    git = ["git", "-C", str(Path(__file__).resolve().parents[1])]
    try:
        head = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True)
        dirty = subprocess.run(
            [*git, "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True
        )
    except OSError:
        return "unknown"
    if head.returncode != 0:
        return "unknown"
    return head.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")


def train_steps(
    model: nn.Module, loss_fn, steps: int, lr: float, checkpoint: Path, every: int
) -> None:
    """Adam with a cosine learning rate, resumable: the optimiser, the step and the model are
    saved every ``every`` steps; batches and dropout are seeded by the step, so a resumed run
    takes the same steps as an uninterrupted one."""
    optimizer = torch.optim.Adam(model.parameters(), lr=lr)
    start = 0
    if checkpoint.exists():
        state = torch.load(checkpoint, weights_only=True)
        model.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])
        start = state["step"]
    model.train()
    with typer.progressbar(
        range(start, steps), length=steps - start, label=checkpoint.stem, file=sys.stderr
    ) as bar:
        for step in bar:
            for group in optimizer.param_groups:
                group["lr"] = lr * 0.5 * (1 + math.cos(math.pi * step / steps))
            torch.manual_seed(step)
            loss = loss_fn(model, step)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            if (step + 1) % every == 0 or step + 1 == steps:
                state = {"model": model.state_dict(), "optimizer": optimizer.state_dict()}
                partial = checkpoint.with_suffix(".partial")
                torch.save({**state, "step": step + 1}, partial)
                partial.replace(checkpoint)
    model.eval()


def _pair_slices(matches: torch.Tensor, count: int) -> list[torch.Tensor]:
    """Matches (sorted by pair id) split per pair."""
    ends = torch.searchsorted(matches[:, 0].contiguous(), torch.arange(1, count + 1))
    return list(torch.tensor_split(matches, ends[:-1]))


def _detector_config(config: PipelineConfig, size: tuple[int, int, int]) -> PipelineConfig:
    n, m, kernel = size
    return config.replace(detector_n=n, detector_m=m, detector_kernel=kernel)


def _size_name(size: tuple[int, int, int]) -> str:
    return "n{}m{}k{}".format(*size)


@torch.no_grad()
def _maps(detector: nn.Module, pairs: ViewPairs) -> torch.Tensor:
    n, _, s, _ = pairs.images.shape
    return detector(pairs.images.view(-1, 1, s, s)).view(n, 2, s, s)


def _params(net: nn.Module) -> int:
    return sum(p.numel() for p in net.parameters())


class Training:
    """One run of the plan, with its work folder."""

    def __init__(self, plan: TrainPlan, work: Path):
        self.plan, self.work = plan, work
        self.config = plan.pipeline
        work.mkdir(parents=True, exist_ok=True)
        self.times_file = work / "seconds.json"
        self.times = json.loads(self.times_file.read_text()) if self.times_file.exists() else {}

    def timed_call(self, name: str, start: float) -> None:
        self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - start
        self.times_file.write_text(json.dumps(self.times, indent=1))

    def data(self) -> dict:
        """Training and held-out view pairs (different seeds, so different shapes) and matches."""
        path = self.work / "data.pt"
        if path.exists():
            saved = torch.load(path, weights_only=True)
            return {k: ViewPairs(**v) if k.endswith("pairs") else v for k, v in saved.items()}
        start = time.perf_counter()
        p, families = self.plan, list(FAMILIES)
        train = render_pairs(
            self.config, families, p.shapes_per_family, p.pairs_per_shape, seed=p.seed
        )
        heldout = render_pairs(
            self.config,
            families,
            p.heldout_shapes_per_family,
            p.heldout_pairs_per_shape,
            seed=p.seed + 1,
        )
        data = {
            "train_pairs": train,
            "heldout_pairs": heldout,
            "train_matches": sample_matches(train, self.config, p.matches_per_pair, BORDER, p.seed),
            "heldout_matches": sample_matches(
                heldout, self.config, p.matches_per_pair, BORDER, p.seed + 1
            ),
        }
        torch.save(
            {k: v.to_dict() if isinstance(v, ViewPairs) else v for k, v in data.items()}, path
        )
        self.timed_call("data", start)
        return data

    def detector(self, size: tuple[int, int, int], data: dict) -> PoIDetector:
        p = self.plan
        torch.manual_seed(p.seed)
        detector = PoIDetector(_detector_config(self.config, size))
        pairs = data["train_pairs"]
        per_pair = _pair_slices(data["train_matches"], len(pairs))
        s = self.config.image_size

        def loss_fn(model: nn.Module, step: int) -> torch.Tensor:
            rng = np.random.default_rng([p.seed, 1, step])
            batch = rng.choice(len(pairs), p.detector_batch, replace=False)
            matches = torch.cat(
                [
                    torch.cat([torch.full((len(m), 1), i), m[:, 1:]], 1)
                    for i, m in enumerate(per_pair[j] for j in batch)
                ]
            )
            images = pairs.images[batch].view(-1, 1, s, s)
            maps = model(images).view(len(batch), 2, s, s)
            gen = torch.Generator().manual_seed(int(rng.integers(2**31)))
            return detector_loss(maps, pairs.depth[batch] > 0, matches, gen)[0]

        start = time.perf_counter()
        checkpoint = self.work / f"detector_{_size_name(size)}.pt"
        train_steps(
            detector, loss_fn, p.detector_steps, p.detector_lr, checkpoint, p.checkpoint_every
        )
        self.timed_call(checkpoint.stem, start)
        return detector

    def hardnet(self, width: float, maps: torch.Tensor, matches: torch.Tensor) -> HardNet:
        p = self.plan
        torch.manual_seed(p.seed)
        net = HardNet(self.config.replace(descriptor_width=width))
        size = self.config.patch_size

        def loss_fn(model: nn.Module, step: int) -> torch.Tensor:
            rng = np.random.default_rng([p.seed, 2, step])
            return correspondence_triplet(model, maps, matches, rng, p.hardnet_batch, size)

        start = time.perf_counter()
        checkpoint = self.work / f"hardnet_w{width:g}.pt"
        train_steps(net, loss_fn, p.hardnet_steps, p.hardnet_lr, checkpoint, p.checkpoint_every)
        self.timed_call(checkpoint.stem, start)
        return net


def _ship(metric: DRKFS, path: Path, default: bool) -> dict:
    torch.save(metric.state_dict(), path)
    return {
        "file": path.name,
        "sha256": sha256(path),
        "config": metric.config.to_dict(),
        "default": default,
    }


def metric_stage(
    plan: TrainPlan,
    run: Training,
    size: tuple[int, int, int],
    start: dict[float, DRKFS],
    detectors: dict[tuple[int, int, int], PoIDetector],
    pairs: Correspondences,
) -> tuple[dict, dict[float, DRKFS]]:
    """Fine-tune the correspondence nets (``start``, per width, with the detector of ``size``)
    with each objective at the plan's objective width and choose the objective on the
    benchmark; train every width with it and choose the width; then try the other detector
    sizes at that width and keep the smallest within a point of the best.
    -> (the manifest's "metric" section, the tuned metric per width)."""
    p = plan.metric
    work = run.work / f"metric-{plan_key(p)}"
    stage = MetricStage(p, work, plan.seed + 2, pairs, train_steps, run.timed_call)
    data = stage.data
    config = _detector_config(p.pipeline, size)
    begin = {w: with_nets(config.replace(descriptor_width=w), m.detector, m.descriptor)
             for w, m in start.items()}  # fmt: skip
    chamfer = stage.row("chamfer", None)
    w0 = p.objective_width
    rows = {BASELINE: stage.row(f"baseline_w{w0:g}", begin[w0])}
    tuned = {}
    for objective in p.objectives:
        name = f"{objective}_w{w0:g}"
        tuned[objective] = stage.fine_tune(begin[w0], objective, name)
        rows[objective] = stage.row(name, tuned[objective])
    objective = choose_objective(rows, chamfer)
    nets, widths = {w0: tuned[objective]}, {w0: rows[objective]}
    for w in plan.widths:
        if w != w0:
            name = f"{objective}_w{w:g}"
            nets[w] = stage.fine_tune(begin[w], objective, name)
            widths[w] = stage.row(name, nets[w])
    width = choose_smallest(widths, {w: w for w in widths}, chamfer)
    sizes = {_size_name(size): (widths[width], nets[width])}
    for other in plan.detector_sizes:
        if other != size:
            name = f"{objective}_w{width:g}_{_size_name(other)}"
            config = _detector_config(p.pipeline, other).replace(descriptor_width=width)
            begin_other = with_nets(config, detectors[other], start[width].descriptor)
            tuned_other = stage.fine_tune(begin_other, objective, name)
            sizes[_size_name(other)] = (stage.row(name, tuned_other), tuned_other)
    params = {n: _params(m.detector) for n, (_, m) in sizes.items()}
    detector = choose_smallest({n: r for n, (r, _) in sizes.items()}, params, chamfer)
    nets[width] = sizes[detector][1]
    section = {
        "data": {"bases": len(data), "meshes_per_base": data.images.shape[1], "seed": stage.seed},
        "chamfer_l1": chamfer,
        "objectives": {n: {**r, "admissible": admissible(r, chamfer)} for n, r in rows.items()},
        "objective": objective,
        "widths": {
            f"{w:g}": {**r, "admissible": admissible(r, chamfer)} for w, r in widths.items()
        },
        "width": width,
        "detectors": {
            n: {**r, "params": params[n], "admissible": admissible(r, chamfer)}
            for n, (r, _) in sizes.items()
        },
        "detector": detector,
        # the default config uses the metric nets only when they are admissible; else the
        # correspondence nets stay its nets
        "default_nets": "metric" if admissible(sizes[detector][0], chamfer) else "correspondence",
        "rule": f"admissible: above Chamfer-L1 on both halves and retrieval >= {RETRIEVAL}; the "
        f"admissible objective with the best accuracy at width {w0:g}, then the smallest width, "
        f"then the smallest detector, within {ACCURACY_TOLERANCE} of the best admissible "
        "accuracy; the default uses the chosen metric nets if they are admissible",
    }
    return section, nets


def sweep_detectors(
    plan: TrainPlan, run: Training, data: dict
) -> tuple[list[dict], dict[tuple[int, int, int], PoIDetector]]:
    """Train a detector of each size; rows of repeatability on held-out pairs against the
    classical detectors (Harris, DoG) and the untrained nets."""
    config, heldout = run.config, data["heldout_pairs"]
    s = config.image_size
    images, shape = heldout.images.view(-1, 1, s, s), heldout.images.shape
    view = torch.zeros(1, 1, s, s)
    rows = [
        {"detector": name, "repeatability": repeatability(response.view(shape), heldout, config)}
        for name, response in (("harris", harris(images)), ("dog", difference_of_gaussians(images)))
    ]
    detectors = {}
    for size in plan.detector_sizes:
        torch.manual_seed(plan.seed)
        untrained = PoIDetector(_detector_config(config, size))
        detectors[size] = run.detector(size, data)
        rows.append(
            {
                "detector": _size_name(size),
                "params": _params(detectors[size]),
                "flops_per_view": conv_flops(detectors[size], view),
                "repeatability": repeatability(_maps(detectors[size], heldout), heldout, config),
                "repeatability_untrained": repeatability(
                    _maps(untrained, heldout), heldout, config
                ),
            }
        )
    return rows, detectors


def select_detector(plan: TrainPlan, rows: list[dict], detectors: dict) -> tuple[int, int, int]:
    """The smallest detector within REPEAT_TOLERANCE of the best trained repeatability."""
    trained = [r for r in rows if "params" in r]
    best = max(r["repeatability"] for r in trained)
    return min(
        (
            size
            for size, r in zip(plan.detector_sizes, trained, strict=True)
            if r["repeatability"] >= best - REPEAT_TOLERANCE
        ),
        key=lambda size: _params(detectors[size]),
    )


def sweep_widths(
    plan: TrainPlan, run: Training, data: dict, train_maps: torch.Tensor, heldout_maps: torch.Tensor
) -> tuple[dict[float, HardNet], list[dict]]:
    """Train HardNet at each width on the chosen detector's maps; rows of held-out FPR95
    against the untrained nets."""
    config, heldout_matches = run.config, data["heldout_matches"]
    nets, rows = {}, []
    patch = torch.zeros(1, 1, config.patch_size, config.patch_size)
    for width in plan.widths:
        nets[width] = run.hardnet(width, train_maps, data["train_matches"])
        torch.manual_seed(plan.seed)
        untrained = HardNet(config.replace(descriptor_width=width)).eval()
        rows.append(
            {
                "width": width,
                "params": _params(nets[width]),
                "flops_per_patch": conv_flops(nets[width], patch),
                "fpr95": descriptor_fpr95(
                    nets[width], heldout_maps, heldout_matches, config.patch_size, plan.seed
                ),
                "fpr95_untrained": descriptor_fpr95(
                    untrained, heldout_maps, heldout_matches, config.patch_size, plan.seed
                ),
            }
        )
    return nets, rows


def select_width(rows: list[dict]) -> float:
    """The smallest width within FPR95_TOLERANCE of the best FPR95."""
    best = min(r["fpr95"] for r in rows)
    return min(r["width"] for r in rows if r["fpr95"] <= best + FPR95_TOLERANCE)


def ship(
    plan: TrainPlan, out: Path, correspondence: dict, tuned: dict, metric_rows: dict
) -> list[dict]:
    """Write every width's correspondence and metric weights into ``out``; the default config's
    are the chosen metric nets, or the correspondence nets at the width the objectives were
    compared at. Returns their manifest entries."""
    out.mkdir(parents=True, exist_ok=True)
    default = (
        ("metric", metric_rows["width"])
        if metric_rows["default_nets"] == "metric"
        else ("correspondence", plan.metric.objective_width)
    )
    return [
        _ship(m, out / f"drkfs_{nets}_w{w:g}.pt", (nets, w) == default)
        for nets, trained in (("correspondence", correspondence), ("metric", tuned))
        for w, m in trained.items()
    ]


def train(plan: TrainPlan, out: Path, work: Path, command: str) -> dict:
    """Run the plan: sweep and select the detector, then HardNet's width, fine-tune both in the
    metric's terms, ship the weights. Writes ``out/drkfs_{correspondence,metric}_w*.pt`` and
    ``out/manifest.json``; returns the manifest."""
    commit = git_commit()  # the code that runs, before anyone edits the tree during the run
    run = Training(plan, work / plan_key(plan))
    config = run.config
    data = run.data()
    heldout, heldout_matches = data["heldout_pairs"], data["heldout_matches"]

    detector_rows, detectors = sweep_detectors(plan, run, data)
    size = select_detector(plan, detector_rows, detectors)
    detector = detectors[size]
    train_maps, heldout_maps = _maps(detector, data["train_pairs"]), _maps(detector, heldout)
    nets, descriptor_rows = sweep_widths(plan, run, data, train_maps, heldout_maps)
    width = select_width(descriptor_rows)

    correspondence = {
        w: with_nets(_detector_config(config, size).replace(descriptor_width=w), detector, net)
        for w, net in nets.items()
    }
    pairs = Correspondences(train_maps, data["train_matches"])
    metric_rows, tuned = metric_stage(plan, run, size, correspondence, detectors, pairs)
    entries = ship(plan, out, correspondence, tuned, metric_rows)

    manifest = {
        "command": command,
        "seed": plan.seed,
        "commit": commit,
        "torch": torch.__version__,
        "plan": asdict(plan),
        "data": {
            "families": list(FAMILIES),
            "train": {
                "shapes": plan.shapes_per_family * len(FAMILIES),
                "view_pairs": len(data["train_pairs"]),
                "matches": len(data["train_matches"]),
            },
            "heldout": {
                "shapes": plan.heldout_shapes_per_family * len(FAMILIES),
                "view_pairs": len(heldout),
                "matches": len(heldout_matches),
            },
        },
        "seconds": run.times,
        "detectors": detector_rows,
        "descriptors": descriptor_rows,
        "choice": {
            "detector": _size_name(size),
            "width": width,
            "rule": f"smallest detector within {REPEAT_TOLERANCE} repeatability and smallest "
            f"width within {FPR95_TOLERANCE} FPR95 point of the best",
        },
        "metric": metric_rows,
        "weights": entries,
    }
    (out / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest
