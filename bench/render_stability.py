"""How much each example variant changes the rendered views (mean and max |difference|).

    python bench/render_stability.py [--out bench/results/render_stability.json]

Renders the bundled example chairs at the paper's config with the reference's joint frame and
compares every variant's 25 views with the reference's. Retessellation should move the image far
less than any geometric edit.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch

from drkfs_onnx import PipelineConfig
from drkfs_onnx.contract.mesh import normalize_pair
from drkfs_onnx.render.renderer import Renderer
from drkfs_onnx.render.torch_ops import TORCH_OPS
from drkfs_onnx.synthetic.examples import REFERENCE, example_meshes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="the JSON to write (default: print only)")
    args = parser.parse_args()
    config = PipelineConfig.paper()  # the committed measurement's cameras
    renderer = Renderer(config)
    meshes = example_meshes()
    reference = meshes[REFERENCE][1]
    ref_verts = torch.tensor(reference.vertices, dtype=torch.float32)

    def render(mesh) -> torch.Tensor:
        verts = torch.tensor(mesh.vertices, dtype=torch.float32)
        verts, _ = normalize_pair(verts, ref_verts, ops=TORCH_OPS)
        with torch.no_grad():
            return renderer.render(verts, torch.tensor(mesh.faces))

    base = render(reference)
    rows = []
    for name, (change, mesh) in meshes.items():
        if name == REFERENCE:
            continue
        diff = (render(mesh) - base).abs()
        rows.append(
            {
                "mesh": name,
                "change": change,
                "mean_abs": float(diff.mean()),
                "max_abs": float(diff.max()),
            }
        )
    report = {
        "command": "python bench/render_stability.py" + (f" --out {args.out}" if args.out else ""),
        "config": config.to_dict(),
        "rows": rows,
    }
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(report, indent=2) + "\n")
    for row in rows:
        mesh, mean, peak = row["mesh"], row["mean_abs"], row["max_abs"]
        print(f"{mesh:28} mean {mean:.2e}  max {peak:.3f}  {row['change']}")


if __name__ == "__main__":
    main()
