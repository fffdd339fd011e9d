"""The soft rasteriser: sparse pairs equal the dense definition, gradients are right and finite."""

import warnings

import numpy as np
import pytest
import torch
from conftest import icosphere
from dense_reference import dense_render

from drkfs_onnx.contract.cameras import make_cameras
from drkfs_onnx.contract.config import TWO_SIDED, PipelineConfig
from drkfs_onnx.contract.render_equations import face_orientation, mesh_orientation
from drkfs_onnx.render.renderer import Renderer
from drkfs_onnx.render.torch_ops import TORCH_OPS
from drkfs_onnx.synthetic.shapes import assemble, chair

# two-sided light, as the dense reference lights; the tests of faces seen from behind move it
SMALL = PipelineConfig(turn_degrees=0.0, num_views=3, image_size=40, **TWO_SIDED)
EYES = make_cameras(PipelineConfig()).eyes


def _tensors(verts, faces, dtype=torch.float64):
    return torch.as_tensor(verts, dtype=dtype), torch.as_tensor(faces, dtype=torch.long)


def _chair():
    verts, faces = assemble(chair())
    return verts - verts.mean(0), faces


def _posed(verts: np.ndarray) -> np.ndarray:
    """A fixed generic rotation: symmetric meshes can put a pixel centre exactly on an edge,
    where any two implementations may disagree on inside/outside by rounding (a d^2/2 sigma
    jump of ~1e-5)."""
    q, _ = np.linalg.qr(np.random.default_rng(7).normal(size=(3, 3)))
    return verts @ q.T


@pytest.mark.parametrize("mode", ["shaded", "silhouette"])
@pytest.mark.parametrize("sigma", [1e-5, 1e-3])
@pytest.mark.parametrize("mesh", [icosphere, _chair])
def test_sparse_renderer_equals_dense_reference(mesh, sigma, mode):
    config = SMALL.replace(sigma=sigma)
    verts, faces = mesh()
    verts, faces = _tensors(_posed(verts), faces)
    sparse = Renderer(config).render(verts, faces, mode=mode)
    dense = dense_render(verts, faces, make_cameras(config), config, mode)
    assert sparse.shape == (3, 40, 40)
    assert (sparse - dense).abs().max() <= 1e-5


def test_image_shows_the_mesh_on_background():
    verts, faces = _tensors(*icosphere(2), dtype=torch.float32)
    images = Renderer(PipelineConfig.paper(num_views=4)).render(verts, faces)
    assert images.shape == (4, 256, 256)
    assert images[:, 0, 0].eq(0).all(), "corners are background"
    centre = images[:, 128, 128]
    assert (centre > 0.3).all() and (centre <= 1).all()


def test_render_gradcheck_float64():
    config = PipelineConfig(
        turn_degrees=0.0, num_views=2, image_size=10, patch_size=8, sigma=2e-3, gamma=5e-2
    )
    rng = np.random.default_rng(1)
    verts = torch.tensor(rng.uniform(-0.6, 0.6, (5, 3)), requires_grad=True)
    faces = torch.tensor([[0, 1, 2], [1, 3, 2], [2, 3, 4]])
    renderer = Renderer(config)
    probe = torch.tensor(rng.normal(size=(2, 10, 10)))
    for mode in ("shaded", "silhouette"):
        torch.autograd.gradcheck(
            lambda v, m=mode: (renderer.render(v, faces, mode=m) * probe).sum(),
            (verts,),
            eps=1e-6,
            atol=1e-5,
        )


def _grad_of_render(verts, faces, config=SMALL):
    verts = verts.clone().requires_grad_(True)
    images = Renderer(config).render(verts, faces)
    (images * torch.linspace(0, 1, images.numel()).view_as(images)).sum().backward()
    return images, verts.grad


@pytest.mark.parametrize(
    "case",
    ["degenerate", "back_faces", "behind_camera", "partly_outside", "far_outside"],
)
def test_hard_cases_give_finite_images_and_gradients(case):
    verts, faces = _tensors(*icosphere(1))
    if case == "degenerate":
        verts = torch.cat([verts, verts[:1], verts[:1] + 1e-9])
        faces = torch.cat([faces, torch.tensor([[0, 42, 43], [1, 1, 2], [3, 4, 3]])])
    elif case == "back_faces":
        faces = faces[:, [0, 2, 1]]
    elif case == "behind_camera":
        verts = verts * 4.0  # reaches past every camera
    elif case == "partly_outside":
        verts = verts + torch.tensor([0.9, 0.0, 0.0])
    elif case == "far_outside":
        verts = verts + torch.tensor([50.0, 0.0, 0.0])
    images, grad = _grad_of_render(verts, faces)
    assert torch.isfinite(images).all()
    assert torch.isfinite(grad).all()
    assert (images >= 0).all() and (images <= 1 + 1e-6).all()


def test_back_faces_render_like_front_faces():
    """Two-sided shading: flipping every face's winding leaves the image unchanged."""
    verts, faces = _tensors(*icosphere(1))
    renderer = Renderer(SMALL)
    front = renderer.render(verts, faces)
    assert torch.allclose(front, renderer.render(verts, faces[:, [0, 2, 1]]), atol=1e-9)


def _bowl():
    """A sphere with its top cut away: the cameras above see its inside through the opening."""
    verts, faces = icosphere(3)
    return verts, faces[verts[faces].mean(1)[:, 1] < 0.25]


def test_a_mesh_wound_inside_out_is_oriented_by_its_signed_volume():
    """Which side of a face is its outside comes from the mesh's winding, turned by the sign of
    its volume: a sphere wound inside out renders as the sphere at any light on faces seen from
    behind, and an open bowl reads outward like the sphere it was cut from."""
    verts, faces = _tensors(*icosphere(2))
    inside_out = faces[:, [0, 2, 1]]
    assert mesh_orientation(verts, faces, TORCH_OPS).tolist() == [1.0]
    assert mesh_orientation(verts, inside_out, TORCH_OPS).tolist() == [-1.0]
    assert mesh_orientation(*_tensors(*_bowl()), TORCH_OPS).tolist() == [1.0]
    # a flat relief, roughened or not, has no volume to tell its outside by: its winding stands
    grid = np.stack(np.meshgrid(np.linspace(-0.7, 0.7, 8), np.linspace(-0.7, 0.7, 8)), -1)
    flat = np.concatenate([grid.reshape(-1, 2), np.zeros((64, 1))], 1)
    rough = flat + [0, 0, 0.01] * np.random.default_rng(2).normal(size=(64, 1))
    corner = np.array([8 * r + c for r in range(7) for c in range(7)])[:, None]
    cells = np.concatenate([corner + [0, 1, 9], corner + [0, 9, 8]])
    for relief in (flat, rough):
        for winding in (cells, cells[:, ::-1].copy()):
            assert mesh_orientation(*_tensors(relief, winding), TORCH_OPS).tolist() == [1.0]
    for share in (0.0, 1.0):
        renderer = Renderer(SMALL.replace(back_light=share))
        front = renderer.render(verts, faces)
        assert torch.allclose(renderer.render(verts, inside_out), front, atol=1e-9)


def test_faces_seen_from_behind_take_back_light_of_the_diffuse_light():
    """Through the bowl's opening the cameras see its inside, faces seen from behind: at
    back_light 0 they lie in the shell's shadow (ambient light alone), at 1 they are lit as
    their fronts, and in between the image moves in proportion (the blend is linear in the
    faces' greys). Faces seen from the front are lit alike at any share."""
    verts, faces = _tensors(*_bowl())

    def render(share, faces=faces):
        return Renderer(SMALL.replace(back_light=share)).render(verts, faces)

    lit, shadowed = render(1.0), render(0.0)
    inside = (shadowed - SMALL.ambient).abs() < 1e-9
    assert inside.sum() > 100 and (lit[inside] > SMALL.ambient + 0.1).float().mean() > 0.5
    assert (shadowed <= lit + 1e-9).all()
    assert torch.allclose(render(0.25), 0.75 * shadowed + 0.25 * lit, atol=1e-9)
    sphere = _tensors(*icosphere(2))[1]
    covered = Renderer(SMALL).render(verts, sphere, mode="silhouette") > 0.999
    for share in (0.0, 0.3):
        assert torch.allclose(render(share, sphere)[covered], render(1.0, sphere)[covered])


def test_pushed_back_faces_seen_from_behind_shade_only_openings():
    """Where two faces meet at an outline, one seen from the front and one from behind, the soft
    depth order blends both into its pixels: unpushed, the shadow darkens every closed mesh's
    outline. Pushed back by back_push, a face seen from behind shows only where no face seen
    from the front reaches: a closed mesh renders as under two-sided light, and the bowl's
    inside as in the unpushed shadow, but for pixels at its rim."""
    pushed = SMALL.replace(back_light=0.0, back_push=0.1)
    lit_renderer, pushed_renderer = Renderer(SMALL), Renderer(pushed)
    for closed in (icosphere(3), _chair()):
        verts, faces = _tensors(*closed)
        lit = lit_renderer.render(verts, faces)
        unpushed = Renderer(SMALL.replace(back_light=0.0)).render(verts, faces)
        assert (lit - unpushed).abs().max() > 0.1
        assert (pushed_renderer.render(verts, faces) - lit).abs().max() < 1e-9
    verts, faces = _tensors(*_bowl())
    shadowed = Renderer(SMALL.replace(back_light=0.0)).render(verts, faces)
    inside = (shadowed - SMALL.ambient).abs() < 1e-9
    shade = pushed_renderer.render(verts, faces)
    assert ((shade - shadowed).abs() < 1e-9)[inside].float().mean() > 0.9


def test_pushed_shadow_gradcheck_float64():
    """The pushed shadow's second blend passes the gradient too: both blends' pairs move."""
    config = PipelineConfig(
        turn_degrees=0.0, num_views=2, image_size=10, patch_size=8, sigma=2e-3, gamma=5e-2,
        back_light=0.2, back_push=0.05,
    )  # fmt: skip
    rng = np.random.default_rng(3)
    verts = torch.tensor(rng.uniform(-0.6, 0.6, (5, 3)), requires_grad=True)
    faces = torch.tensor([[0, 1, 2], [1, 3, 2], [2, 3, 4]])
    renderer = Renderer(config)
    probe = torch.tensor(rng.normal(size=(2, 10, 10)))
    torch.autograd.gradcheck(
        lambda v: (renderer.render(v, faces) * probe).sum(), (verts,), eps=1e-6, atol=1e-5
    )


def test_retessellation_barely_changes_the_image():
    """Splitting every triangle into four keeps the surface, so the render stays nearly equal,
    far closer than moving one leg by 2%."""
    from drkfs_onnx.synthetic.variants import shifted

    base = chair()
    renderer = Renderer(PipelineConfig(turn_degrees=0.0, num_views=6, image_size=128))

    def render(parts, subdivisions=1):
        verts, faces = _tensors(*assemble(parts, subdivisions), dtype=torch.float32)
        return renderer.render(verts - torch.tensor([0.0, 0.5, 0.0]), faces)

    reference = render(base)
    retessellated = (render(base, 2) - reference).abs().mean()
    leg_moved = (render(shifted(base, "leg_3", (0.02, 0, 0))) - reference).abs().mean()
    assert retessellated < leg_moved / 3


def test_cost_follows_covered_pairs_not_pixels_times_faces():
    """A mesh far outside every view produces no pixel-face pair at all; inside, the pairs
    enumerated are a small share of pixels x faces and at most three times those covered."""
    from drkfs_onnx.render.mesh_batch import MeshBatch
    from drkfs_onnx.render.pair_plan import PairPlan

    verts, faces = _tensors(*icosphere(1))
    renderer = Renderer(SMALL)
    for offset, expect_pairs in ((0.0, True), (50.0, False)):
        moved = verts + torch.tensor([offset, 0.0, 0.0])
        _, screen = renderer.screen(MeshBatch.of(moved, faces))
        enumerated = PairPlan(screen, SMALL).num_pairs()
        covered = len(renderer.rasterize(moved, faces, depth_cull=False).pixel)
        assert (enumerated > 0) == expect_pairs and (covered > 0) == expect_pairs
        if expect_pairs:
            assert covered <= enumerated < min(3 * covered, 3 * 40 * 40 * len(faces) / 20)


@pytest.mark.parametrize("sigma", [1e-5, 1e-3])
@pytest.mark.parametrize("mesh", [icosphere, _chair])
def test_pair_plan_lists_every_covered_pair(mesh, sigma):
    """The plan lists, of each face's box, only the columns of each row near its edge lines:
    every pixel-face pair that every pixel against every face finds covered, and far fewer
    uncovered pairs than the boxes hold."""
    from drkfs_onnx.contract.render_equations import pair_terms, pixel_centre, pixel_span
    from drkfs_onnx.render.mesh_batch import MeshBatch
    from drkfs_onnx.render.pair_plan import PairPlan
    from drkfs_onnx.render.torch_ops import TORCH_OPS

    config = SMALL.replace(sigma=sigma)
    verts, faces = mesh()
    verts, faces = _tensors(_posed(verts), faces, dtype=torch.float32)
    _, screen = Renderer(config).screen(MeshBatch.of(verts, faces))
    plan = PairPlan(screen, config)
    count = len(screen.visible)
    listed = torch.cat([pairs.pixel * count + pairs.face for pairs in plan])
    size, per_view = config.image_size, screen.num_faces
    pixel = torch.arange(screen.num_views * size * size)
    face = pixel[:, None] // (size * size) * per_view + torch.arange(per_view)  # its view's
    pixel, face = pixel[:, None].expand_as(face).reshape(-1), face.reshape(-1)
    px = pixel_centre((pixel % size).float(), size)
    py = pixel_centre((pixel // size % size).float(), size)
    coverage, _ = pair_terms(screen.params[:, face], px, py, config, TORCH_OPS)
    covered = (pixel * count + face)[(coverage > 0) & screen.visible[face]]
    assert len(covered) > 1000
    assert torch.isin(covered, listed).all()
    xs, ys = screen.params[0:6:2], screen.params[1:6:2]
    boxes = [pixel_span(v.amin(0), v.amax(0), config, TORCH_OPS)[1] for v in (xs, ys)]
    assert len(listed) < 0.9 * float((boxes[0] * boxes[1] * screen.visible).sum())


@pytest.mark.parametrize("sigma", [1e-5, 1e-3])
def test_pair_terms_grad_is_autograds_gradient_of_pair_terms(sigma):
    """The backward pass's written-out gradient equals autograd's through ``pair_terms``, for
    pixels inside, near and far from triangles of every orientation, depths clamped or not
    (each pair a face of its own: its parts are its face's sums)."""
    from drkfs_onnx.contract.render_equations import face_params_grad, pair_terms, pair_terms_grad
    from drkfs_onnx.render.torch_ops import TORCH_OPS

    config = PipelineConfig(sigma=sigma)
    generator = torch.Generator().manual_seed(0)
    count = 20_000
    tri = torch.rand(9, count, generator=generator, dtype=torch.float64) * 0.4 - 0.2
    tri[6:] = torch.rand(3, count, generator=generator, dtype=torch.float64)
    px, py = torch.rand(2, count, generator=generator, dtype=torch.float64) * 0.5 - 0.25
    grad_coverage, grad_depth = torch.randn(2, count, generator=generator, dtype=torch.float64)
    leaf = tri.clone().requires_grad_(True)
    coverage, depth = pair_terms(leaf, px, py, config, TORCH_OPS)
    assert 0.05 < float((coverage > 0).double().mean()) < 0.95
    (grad_coverage * coverage + grad_depth * depth).sum().backward()
    parts = pair_terms_grad(
        tri, px, py, coverage.detach(), grad_coverage, grad_depth, config, TORCH_OPS
    )
    found = face_params_grad(tri, parts, TORCH_OPS)
    # within 1e-8 of the largest: the written-out slope of t leaves out TINY in its denominator
    assert torch.allclose(found, leaf.grad, rtol=1e-8, atol=1e-8 * float(leaf.grad.abs().max()))


@pytest.mark.parametrize("equation", ["terms_and_logits", "terms_grad_at"])
def test_the_compiled_pair_equations_trace_as_one_graph(equation):
    """A GPU compiles the rasteriser's per-pair equations (``compile_policy.fused``); a graph
    break in them leaves torch.compile running the pieces between breaks one op at a time.
    Traced only, so no compiler is needed."""
    from drkfs_onnx.render import kept_pairs, pixel_sums
    from drkfs_onnx.render.torch_ops import TORCH_OPS

    config, count = PipelineConfig(), 500
    generator = torch.Generator().manual_seed(0)
    params = torch.rand(9, 100, generator=generator)
    face = torch.randint(0, 100, (count,), generator=generator, dtype=torch.int32)
    pair_values = torch.rand(4, count, generator=generator)
    pixel = torch.randint(0, config.num_views * config.image_size**2, (count,))
    inputs = {
        "terms_and_logits": (params, face, pair_values[0], pair_values[1]),
        "terms_grad_at": (params, face, pixel, *pair_values[:3]),
    }[equation]
    function = {"terms_and_logits": kept_pairs, "terms_grad_at": pixel_sums}[equation]
    function = getattr(function, "_" + equation)

    def traced(*tensors):
        return function(*tensors, config, TORCH_OPS)

    explained = torch._dynamo.explain(traced)(*inputs)
    assert (explained.graph_count, explained.graph_break_count) == (1, 0), explained.break_reasons


def test_the_compiled_pair_equations_keep_eager_numerics():
    """Inductor's GPU defaults (fused multiply-adds, approximate division) turned the paper
    config's gradient from the CPU's (cosine 0.991 on an H200); the pinned torch knows the
    settings that keep each step's rounding (the division's by its name in this torch), so the
    compiled equations ask for them."""
    from drkfs_onnx.render.compile_policy import compile_options

    options = compile_options()
    assert options.pop("emulate_precision_casts") is True
    assert list(options.values()) == [True]  # the division's setting, under one of its names


def test_a_cpu_compiles_the_equations_for_training_steps_only(monkeypatch):
    """DRKFS_COMPILE='auto' (the default) compiles the per-pair equations on a GPU, and on a CPU
    where the render is differentiable: a training step repays the compile, one evaluation on
    a CPU would wait for it. '0' and '1' decide on every device; anything else is refused."""
    from drkfs_onnx.render.compile_policy import compiles

    wanted = {"auto": [False, True, True, True], "0": [False] * 4, "1": [True] * 4}
    for setting, expected in wanted.items():
        monkeypatch.setenv("DRKFS_COMPILE", setting)
        found = [compiles(d, grad) for d in ("cpu", "cuda") for grad in (False, True)]
        assert found == expected, setting
    monkeypatch.setenv("DRKFS_COMPILE", "yes")
    with pytest.raises(ValueError, match="DRKFS_COMPILE='yes': use one of auto, 0, 1"):
        compiles("cpu", True)


def _render_with_gradient(config: PipelineConfig) -> tuple[torch.Tensor, torch.Tensor]:
    return _grad_of_render(*_tensors(*_chair(), dtype=torch.float32), config)


def test_equations_that_fail_to_compile_run_eagerly_after_one_warning(monkeypatch, compile_setting):
    """Where torch.compile fails (a CPU without a C++ compiler, say), each equation warns once,
    with the reason, and runs eagerly from then on: the same images and gradient as eager."""
    config = PipelineConfig(turn_degrees=0.0, num_views=2, image_size=32)
    compile_setting("0")
    expected = _render_with_gradient(config)

    def no_compiler(function, **options):
        def fails(*tensors):
            raise RuntimeError("InvalidCxxCompiler: No working C++ compiler found\ndetails")

        return fails

    monkeypatch.setattr(torch, "compile", no_compiler)
    compile_setting("1")
    with pytest.warns(RuntimeWarning) as caught:
        found = _render_with_gradient(config)
        found_again = _render_with_gradient(config)
    messages = [str(w.message) for w in caught]
    assert len(messages) == 2  # the forward's equation and the backward's, once each
    assert all("torch.compile failed (InvalidCxxCompiler: No working C++" in m for m in messages)
    for a, b, c in zip(expected, found, found_again, strict=True):
        assert torch.equal(a, b) and torch.equal(a, c)


@pytest.mark.slow  # a cold compile takes CI's 2 cores about 30 s
def test_a_cpu_training_step_compiles_its_equations_and_agrees_with_eager(compile_setting):
    """The default on a CPU: a differentiable render runs the compiled equations (no fallback
    warning) and gives eager's images and gradient to float32 rounding."""
    from drkfs_onnx.render.compile_policy import CompiledOrEager, fused
    from drkfs_onnx.render.kept_pairs import _terms_and_logits
    from drkfs_onnx.render.pixel_sums import _terms_grad_at

    config = PipelineConfig(turn_degrees=0.0, num_views=2, image_size=32)
    compile_setting("0")
    eager = _render_with_gradient(config)
    compile_setting("auto")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        compiled = _render_with_gradient(config)
    for equation in (_terms_and_logits, _terms_grad_at):
        compiled_equation = fused(equation, config, "cpu", True)
        assert isinstance(compiled_equation, CompiledOrEager)
        assert compiled_equation.compiled is not None
    torch.testing.assert_close(compiled[0], eager[0], rtol=1e-6, atol=1e-6)
    gradients = torch.stack([eager[1].flatten(), compiled[1].flatten()])
    assert float(torch.nn.functional.cosine_similarity(*gradients, dim=0)) > 0.99999


def test_each_face_is_oriented_by_its_surface_not_by_how_the_file_winds_it():
    """``winding='geometry'``: faces flipped at random, a part wound against the rest, a mesh
    wound inside out, an unwelded soup and double-sided copies each read outward; a flat relief
    has no volume to tell its outside by and shows the cameras above the side they see."""
    rng = np.random.default_rng(0)
    verts, faces = _chair()
    assert (face_orientation(verts, faces, EYES) == 1.0).all()
    flipped = rng.random(len(faces)) < 0.5
    wound = np.where(flipped[:, None], faces[:, ::-1], faces)
    np.testing.assert_array_equal(
        face_orientation(verts, wound, EYES), np.where(flipped, -1.0, 1.0)
    )
    np.testing.assert_array_equal(face_orientation(verts, faces[:, ::-1], EYES), -1.0)
    soup = verts[wound].reshape(-1, 3)  # every face its own three vertices
    np.testing.assert_array_equal(
        face_orientation(soup, np.arange(len(soup)).reshape(-1, 3), EYES),
        np.where(flipped, -1.0, 1.0),
    )
    both = np.concatenate([faces, faces[:, ::-1]])  # double-sided: each face and its reverse
    np.testing.assert_array_equal(
        face_orientation(verts, both, EYES), np.r_[np.ones(len(faces)), -np.ones(len(faces))]
    )
    grid = np.stack(np.meshgrid(np.linspace(-0.7, 0.7, 8), np.linspace(-0.7, 0.7, 8)), -1)
    flat = np.concatenate([grid.reshape(-1, 2), np.zeros((64, 1))], 1)
    corner = np.array([8 * r + c for r in range(7) for c in range(7)])[:, None]
    cells = np.concatenate([corner + [0, 1, 9], corner + [0, 9, 8]])
    # a relief has no volume to tell its outside by: the side the cameras above see is
    relief = flat[:, [0, 2, 1]]  # lying under the cameras, through the origin
    for winding in (cells, cells[:, ::-1]):
        edges = (relief[winding[:, k]] - relief[winding[:, 0]] for k in (1, 2))
        up = np.sign(np.cross(*edges)[:, 1])
        np.testing.assert_array_equal(face_orientation(relief, winding, EYES), up)


def test_under_the_surfaces_orientation_a_files_winding_does_not_change_the_views():
    verts, faces = _tensors(*_chair())
    flipped = torch.as_tensor(np.random.default_rng(1).random(len(faces)) < 0.5)
    wound = torch.where(flipped[:, None], faces.flip(1), faces)
    for winding, same in (("geometry", True), ("file", False)):
        renderer = Renderer(SMALL.replace(back_light=0.0, back_push=0.05, winding=winding))
        front = renderer.render(verts, faces)
        assert torch.allclose(renderer.render(verts, wound), front, atol=1e-9) == same
