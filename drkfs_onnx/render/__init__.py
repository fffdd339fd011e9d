"""The torch renderer: a sparse soft rasteriser (SoftRas' formulation) sized for a batch of
meshes, and its shaders. Differentiable; the equations are the contract's
(``contract.render_equations``), shared with the numpy renderer of ``runtime/``.

Each face covers pixel p with probability D = sigmoid(+-d^2 / sigma), d the screen distance from
p to the triangle (+ inside, - outside). Like SoftRas' kernel we cut D where it falls below
``coverage_eps``; we shift and rescale it there, D' = max(D - eps, 0) / (1 - eps), so the cut is
continuous and the function stays smooth for gradients.

Cost grows with the pixel-face pairs within the cut-off radius of each face's edge lines, not
pixels x faces, and a batch of B meshes' K views is one screen of B * K views. One file a step:

1. ``pair_plan``: a ``PairPlan`` enumerates those pairs, a span of columns in each row of a
   face's box, in chunks of ``pair_chunk(device)`` pairs;
2. ``kept_pairs``: their coverage, depth and blend logit without autograd, each pixel's largest
   logit, and the pairs the image is made of, listed once (``KeptPairs``);
3. ``pixel_sums``: a ``Shader``'s per-pair terms summed per pixel; the backward recomputes each
   chunk's edges and sends the pixels' gradients to the faces by ``pair_terms_grad``;
4. ``shading``: the grey Lambertian blend and the silhouette shaders;
5. ``renderer``: ``Renderer``, cameras in, images out, for a ``MeshBatch`` (``mesh_batch``).

``compile_policy`` says where the per-pair equations are compiled; ``torch_ops`` is the torch
``ArrayOps`` they are evaluated with. A step waits for the host three times whatever the batch:
the plan's box rows and chunks, and the kept pairs' count.
"""
