"""A model's graph cut down to its first output, for ``predict``.

onnxruntime runs every node of a graph whatever outputs a call asks for: the general strip
models' graphs compute two check outputs beside the pressure map (the readings residual and
balance, :data:`~tactile_learn.strips_guard.CHECK_OUTPUTS`: 12 of strips16_small's 77 nodes,
four of them MatMuls), which ``predict`` never reads: ~20 us of its ~67 at batch 1 (measured,
docs/speed.md). :func:`first_output_graph` keeps the nodes the first output depends on, the initializers
they read and the graph's metadata; the kept nodes compute what they compute in the whole graph
(tests: bit-identical). It needs the ``onnx`` package (in the runtime extra: ~20 us of
strips16_small's batch 1 is worth the model format's own reader); where it is not installed, or
the graph holds subgraphs (whose outer-scope reads this module does not follow),
``predict`` runs the whole graph as before.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["first_output_graph"]


def first_output_graph(path: str | Path) -> bytes | None:
    """The serialised model at ``path`` with only the first output and the nodes it needs;
    ``None`` where there is nothing to cut (one output, every node needed), where ``onnx`` is
    not installed, or where a node holds a subgraph."""
    try:
        import onnx
    except ImportError:
        return None
    model = onnx.load(str(path))
    graph = model.graph
    if len(graph.output) < 2:
        return None
    subgraphs = (onnx.AttributeProto.GRAPH, onnx.AttributeProto.GRAPHS)
    if any(attribute.type in subgraphs for node in graph.node for attribute in node.attribute):
        return None
    producer = {name: node for node in graph.node for name in node.output if name}
    needed: set[int] = set()
    pending = [graph.output[0].name]
    while pending:
        node = producer.get(pending.pop())
        if node is not None and id(node) not in needed:
            needed.add(id(node))
            pending.extend(name for name in node.input if name)
    if len(needed) == len(graph.node):
        return None
    nodes = [node for node in graph.node if id(node) in needed]  # in the graph's (topological) order
    read = {name for node in nodes for name in node.input}
    kept = read | {name for node in nodes for name in node.output}
    pruned = onnx.helper.make_graph(
        nodes,
        graph.name,
        list(graph.input),
        [graph.output[0]],
        [tensor for tensor in graph.initializer if tensor.name in read],
        value_info=[info for info in graph.value_info if info.name in kept],
    )
    model.graph.CopyFrom(pruned)  # the model's opsets, metadata and producer stay
    return bytes(model.SerializeToString())
