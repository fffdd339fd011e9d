"""What static int8 (QDQ, per-channel) does to the shipped w1 feature graph: speed and accuracy.

    python bench/quantize.py [--out bench/results/quantize.json]

Quantises the paper preset's feature graph (``models/features_correspondence_w1_256px.onnx``)
with onnxruntime (calibrated on renders of six synthetic shapes that the evaluation does not
use), then, in the same run and process, with 2 threads:
seconds per new mesh (render + features, best of 3) for fp32 and int8 as a ratio; and on the
variants of nine other synthetic shapes (two structural and five mild edits each, scored against
their base) the relative score change, Kendall's tau between the two score lists, and whether
each shape's variants come out in the same order. Nothing is shipped by this script.
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import onnx
from onnxruntime.quantization import (
    CalibrationDataReader,
    QuantFormat,
    QuantType,
    quantize_static,
)
from onnxruntime.quantization.shape_inference import quant_pre_process

from drkfs_lab.score import CASES, ROOT, best_time  # bench/score.py: the same meshes and timer
from drkfs_onnx import PipelineConfig, check_mesh, load_mesh
from drkfs_onnx.contract.mesh import frame_of, place
from drkfs_onnx.contract.model_files import features_file
from drkfs_onnx.runtime import Scorer
from drkfs_onnx.runtime.render import NumpyRenderer
from drkfs_onnx.synthetic.shapes import FAMILIES, assemble, random_shape
from drkfs_onnx.synthetic.variants import make_variants

CALIBRATION_SEED, EVALUATION_SEED = 100, 200
VIEW_BATCH = 5


class Renders(CalibrationDataReader):
    """Feature-graph inputs: every patch of VIEW_BATCH views at a time, six families' shapes."""

    def __init__(self, config: PipelineConfig):
        renderer = NumpyRenderer(config, threads=2)
        self.inputs = []
        for i, family in enumerate(sorted(FAMILIES)[:6]):
            verts, faces = assemble(random_shape(family, CALIBRATION_SEED + i), 1)
            views = renderer.render(place(verts, frame_of(verts)), faces)
            views = views[:, None].astype(np.float32)
            for k in range(0, len(views), VIEW_BATCH):
                batch = views[k : k + VIEW_BATCH]
                index = np.arange(len(batch) * config.patches_per_view, dtype=np.int64)
                self.inputs.append({"views": batch, "patch_index": index})
        self.pending = iter(self.inputs)

    def get_next(self):
        return next(self.pending, None)


def quantize(source: Path, target: Path, config: PipelineConfig) -> float:
    """Write the int8 graph with the source's metadata (config, version, weights hash)."""
    start = time.perf_counter()
    prepared = target.with_suffix(".pre.onnx")
    # onnxruntime's symbolic shape inference fails on the dynamo graph's unnamed value infos;
    # ONNX shape inference and the graph optimisation still run
    quant_pre_process(str(source), str(prepared), skip_symbolic_shape=True)
    quantize_static(
        str(prepared),
        str(target),
        Renders(config),
        quant_format=QuantFormat.QDQ,
        per_channel=True,
        activation_type=QuantType.QInt8,
        weight_type=QuantType.QInt8,
    )
    model = onnx.load(str(target))
    del model.metadata_props[:]
    for prop in onnx.load(str(source)).metadata_props:
        model.metadata_props.add(key=prop.key, value=prop.value)
    onnx.save(model, str(target))
    return time.perf_counter() - start


def seconds_per_new_mesh(scorer: Scorer, mesh, repeats: int = 3) -> float:
    def new_mesh():
        scorer.cache.clear()
        return scorer.features(mesh)

    return best_time(new_mesh, repeats)[0]


def kendall_tau(a: np.ndarray, b: np.ndarray) -> float:
    i, j = np.triu_indices(len(a), k=1)
    return float(np.mean(np.sign(a[i] - a[j]) * np.sign(b[i] - b[j])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "quantize.json")
    args = parser.parse_args()
    config = PipelineConfig.paper()  # the committed measurement's config
    with tempfile.TemporaryDirectory() as folder:
        int8 = Path(folder) / "features_w1_int8.onnx"
        quantize_s = quantize(ROOT / "models" / features_file(config), int8, config)
        scorers = {"fp32": Scorer(config, threads=2), "int8": Scorer(config, int8, threads=2)}
        speed = {}
        for name, path in CASES.items():
            mesh = load_mesh(path)
            row = {k: seconds_per_new_mesh(s, mesh) for k, s in scorers.items()}
            speed[name] = {**row, "fp32_over_int8": row["fp32"] / row["int8"]}
        scores = {k: [] for k in scorers}
        same_order, labels = [], []
        for i, family in enumerate(sorted(FAMILIES)):
            parts = random_shape(family, EVALUATION_SEED + i)
            base = check_mesh(*assemble(parts, 1), f"{family} base")
            variants = make_variants(parts, np.random.default_rng(EVALUATION_SEED + i))
            shape_scores = {}
            for kind, scorer in scorers.items():
                shape_scores[kind] = [
                    scorer.score(check_mesh(v.verts, v.faces, v.name), base) for v in variants
                ]
                scores[kind] += shape_scores[kind]
            order = {k: np.argsort(v, kind="stable").tolist() for k, v in shape_scores.items()}
            same_order.append(order["fp32"] == order["int8"])
            labels += [f"{family}/{v.name}" for v in variants]
    fp32, q8 = np.array(scores["fp32"]), np.array(scores["int8"])
    relative = np.abs(q8 - fp32) / np.maximum(fp32, 1e-12)
    results = {
        "command": "python bench/quantize.py",
        "platform": platform.platform(),
        "threads": 2,
        "config": config.to_dict(),
        "quantization": "onnxruntime quantize_static, QDQ, per-channel int8 weights and "
        "activations, calibrated on 6 synthetic shapes x 25 views (all patches)",
        "quantize_seconds": quantize_s,
        "seconds_per_new_mesh": speed,
        "accuracy": {
            "pairs": len(fp32),
            "median_relative_score_change": float(np.median(relative)),
            "max_relative_score_change": float(relative.max()),
            "kendall_tau_of_scores": kendall_tau(fp32, q8),
            "shapes_with_identical_variant_order": f"{sum(same_order)}/{len(same_order)}",
        },
        "scores_fp32_int8": {
            label: [float(a), float(b)] for label, a, b in zip(labels, fp32, q8, strict=True)
        },
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1))
    print(json.dumps({k: results[k] for k in ("seconds_per_new_mesh", "accuracy")}, indent=1))


if __name__ == "__main__":
    main()
