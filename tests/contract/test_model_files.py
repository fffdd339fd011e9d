"""contract/model_files: what the installed models/ hold, by the graphs' names."""

from drkfs_onnx.contract.model_files import held_graphs


def test_held_graphs_lists_each_widths_view_sizes_and_nothing_for_nets_not_shipped():
    assert held_graphs("tolerant") == {0.5: [128, 144]}
    assert held_graphs("correspondence")[1.0] == [128, 144, 256]  # the paper's size too
    assert held_graphs("mystery") == {}
