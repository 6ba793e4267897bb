"""Fewer onnxruntime nodes for the same function: rewrites applied to a graph as it is loaded.

At batch 1 a small network's time under onnxruntime is mostly the cost of starting its nodes
(docs/speed.md, "A cheaper strip graph"), and onnxruntime's own "extended" optimisations leave two
patterns of the exported strip networks unfused:

- **softplus with the exporter's threshold**: torch's ``softplus`` exports as
  ``Where(Greater(x, t), x, Softplus(x))`` (three nodes; with ``beta = b``:
  ``Where(Greater(x b, t), x, Softplus(x b) / b)``). onnxruntime's ``Softplus`` is computed in the
  stable form, and for ``x > t >=`` :data:`SOFTPLUS_EXACT` its value ``x + log1p(exp(-x))`` rounds
  to ``x`` in float32 (``exp(-14) < 2^-20``, half an ulp of any ``x >= 14``), so the bare
  ``Softplus`` (``/ b``) is the same function to float32 rounding: one node (two). A ``b`` that is
  not a power of two is left alone (``(x b) / b`` is then not always ``x``); with a power of two the
  one difference is where ``x b`` overflows float32 (``|x| > 3.4e38 / b``: inf instead of ``x``),
  which a network's bounded activations never reach.
- **a convolution, a full-size sum and a ReLU**: ``Relu(Add(Conv(X, W, B), Z))`` where ``Z`` has
  the convolution's own output shape becomes onnxruntime's contrib ``FusedConv(X, W, B, Z,
  activation="Relu")`` (the convolution accumulates onto ``Z``, then the activation): one node
  instead of three. onnxruntime fuses this itself only in its NCHWc layout ("all"), which slows
  the small strip convolutions (docs/strips.md); ``FusedConv`` is in every onnxruntime build.

The rewrite runs on the loaded model, never on a shipped file: a model on disk stays standard ONNX
(other runtimes read it; its checksum is the card's). Nodes are matched by their tensors' names and
consumers only, and shapes from ONNX's own shape inference; a node whose output is read by any other
node or is a graph output is never folded away. :func:`fuse_for_onnxruntime` returns the number of
rewrites; the serialised model is unchanged when there are none.
"""

from __future__ import annotations

import math
from collections import defaultdict
from typing import Any

__all__ = ["CONTRIB_DOMAIN", "SOFTPLUS_EXACT", "fuse_for_onnxruntime", "fused_model_bytes"]

#: onnxruntime's contrib operator domain (``FusedConv``)
CONTRIB_DOMAIN = "com.microsoft"
#: the smallest ``Where(Greater(x, t), x, Softplus(x))`` threshold at which the bare Softplus rounds
#: to ``x`` above ``t`` in float32 (module docstring)
SOFTPLUS_EXACT = 14.0


def _consumers(graph: Any) -> dict[str, list[Any]]:
    readers: dict[str, list[Any]] = defaultdict(list)
    for node in graph.node:
        for name in node.input:
            if name:
                readers[name].append(node)
    return readers


def _scalar(graph: Any, name: str) -> float | None:
    """The value of a one-element constant (initializer or ``Constant`` node), else ``None``."""
    from onnx import numpy_helper

    for tensor in graph.initializer:
        if tensor.name == name:
            value = numpy_helper.to_array(tensor)
            return float(value.reshape(-1)[0]) if value.size == 1 else None
    for node in graph.node:
        if node.op_type == "Constant" and node.output[0] == name:
            for attribute in node.attribute:
                if attribute.name == "value":
                    value = numpy_helper.to_array(attribute.t)
                    return float(value.reshape(-1)[0]) if value.size == 1 else None
    return None


def _softplus_input(graph: Any, producer: dict[str, Any], value: str, x: str) -> tuple[str, list[Any]] | None:
    """Where ``value`` is ``Softplus(x)`` or ``Softplus(x * b) / b`` (``b`` a power of two: the
    scaling is exact), the Softplus' input and the nodes computing ``value`` from it; else ``None``."""
    node = producer.get(value)
    if node is None:
        return None
    if node.op_type == "Softplus":
        return (node.input[0], [node]) if node.input[0] == x else None
    if node.op_type != "Div" or (soft := producer.get(node.input[0])) is None or soft.op_type != "Softplus":
        return None
    scale, scaled = _scalar(graph, node.input[1]), producer.get(soft.input[0])
    if scale is None or scale <= 0.0 or math.frexp(scale)[0] != 0.5 or scaled is None or scaled.op_type != "Mul":
        return None
    operands = list(scaled.input)
    if x not in operands or _scalar(graph, operands[1 - operands.index(x)]) != scale:
        return None
    return soft.input[0], [node, soft]


def _fuse_softplus(graph: Any) -> int:
    """``Where(Greater(y, t), x, Softplus(y) [/ b])`` with ``y = x [* b]`` -> ``Softplus(y) [/ b]``
    for ``t >= SOFTPLUS_EXACT`` (torch's ``softplus`` with ``beta = b`` and its threshold)."""
    producer = {out: node for node in graph.node for out in node.output}
    readers = _consumers(graph)
    outputs = {value.name for value in graph.output}
    removed: list[Any] = []
    for where in list(graph.node):
        if where.op_type != "Where" or where.domain not in ("", "ai.onnx") or len(where.input) != 3:
            continue
        condition = producer.get(where.input[0])
        found = _softplus_input(graph, producer, where.input[2], where.input[1])
        if condition is None or condition.op_type != "Greater" or found is None:
            continue
        threshold = _scalar(graph, condition.input[1])
        if condition.input[0] != found[0] or threshold is None or threshold < SOFTPLUS_EXACT:
            continue
        last = producer[where.input[2]]
        if any(len(readers[n.output[0]]) != 1 or n.output[0] in outputs for n in (condition, *found[1])):
            continue
        last.output[0] = where.output[0]  # the softplus now writes what the Where wrote
        removed += [condition, where]
    _remove(graph, removed)
    return len(removed) // 2


def _same_shape(a: Any, b: Any) -> bool:
    """Two inferred tensor types of one static rank whose dimensions are equal (values, or the
    same symbolic name); float32 both."""
    if a is None or b is None or a.elem_type != 1 or b.elem_type != 1:  # 1: FLOAT
        return False
    da, db = a.shape.dim, b.shape.dim
    if not a.HasField("shape") or not b.HasField("shape") or len(da) != len(db):
        return False
    for x, y in zip(da, db, strict=True):
        if x.HasField("dim_value") and y.HasField("dim_value"):
            if x.dim_value != y.dim_value:
                return False
        elif not (x.HasField("dim_param") and y.HasField("dim_param") and x.dim_param == y.dim_param):
            return False
    return True


def _fuse_conv_add_relu(model: Any) -> int:
    """``Relu(Add(Conv(X, W, B), Z))``, ``Z`` of the Conv's output shape -> ``FusedConv(X, W, B, Z)``."""
    import onnx

    graph = model.graph
    inferred = onnx.shape_inference.infer_shapes(model, strict_mode=False).graph
    types = {v.name: v.type.tensor_type for v in (*inferred.value_info, *inferred.input, *inferred.output)}
    producer = {out: node for node in graph.node for out in node.output}
    readers = _consumers(graph)
    outputs = {value.name for value in graph.output}
    removed: list[Any] = []
    fused = 0
    for add in list(graph.node):
        if add.op_type != "Add" or add.domain not in ("", "ai.onnx"):
            continue
        after = readers.get(add.output[0], [])
        if len(after) != 1 or after[0].op_type != "Relu" or add.output[0] in outputs:
            continue
        for k in (0, 1):
            conv = producer.get(add.input[k])
            if conv is None or conv.op_type != "Conv" or conv.domain not in ("", "ai.onnx"):
                continue
            if len(readers[conv.output[0]]) != 1 or conv.output[0] in outputs:
                continue
            z = add.input[1 - k]
            if not _same_shape(types.get(conv.output[0]), types.get(z)) or not _same_shape(
                types.get(z), types.get(add.output[0])
            ):
                continue
            relu = after[0]
            inputs = [*conv.input, *([""] * (3 - len(conv.input))), z]
            node = onnx.helper.make_node(
                "FusedConv",
                inputs,
                [relu.output[0]],
                name=f"{conv.name or conv.output[0]}_fused",
                domain=CONTRIB_DOMAIN,
            )
            node.attribute.extend(a for a in conv.attribute)
            node.attribute.append(onnx.helper.make_attribute("activation", "Relu"))
            relu.CopyFrom(node)  # in the ReLU's place: the Conv's inputs and Z are all produced before it
            removed += [conv, add]
            fused += 1
            break
    _remove(graph, removed)
    if fused and not any(op.domain == CONTRIB_DOMAIN for op in model.opset_import):
        model.opset_import.append(onnx.helper.make_opsetid(CONTRIB_DOMAIN, 1))
    return fused


def _remove(graph: Any, nodes: list[Any]) -> None:
    """Drop ``nodes`` and the initializers no node reads any more."""
    gone = {id(node) for node in nodes}
    kept = [node for node in graph.node if id(node) not in gone]
    del graph.node[:]
    graph.node.extend(kept)
    read = {name for node in kept for name in node.input} | {value.name for value in graph.output}
    unread = [tensor for tensor in graph.initializer if tensor.name not in read]
    for tensor in unread:
        graph.initializer.remove(tensor)


def fuse_for_onnxruntime(model: Any) -> int:
    """Rewrite ``model`` (an ``onnx.ModelProto``, in place) with the fusions of the module
    docstring; returns how many were made. Graphs holding subgraphs are left alone."""
    import onnx

    subgraphs = (onnx.AttributeProto.GRAPH, onnx.AttributeProto.GRAPHS)
    if any(a.type in subgraphs for node in model.graph.node for a in node.attribute):
        return 0
    return _fuse_softplus(model.graph) + _fuse_conv_add_relu(model)


def fused_model_bytes(model: bytes) -> bytes:
    """The serialised ``model`` after :func:`fuse_for_onnxruntime` (the same bytes if nothing fused)."""
    import onnx

    proto = onnx.load_from_string(model)
    return bytes(proto.SerializeToString()) if fuse_for_onnxruntime(proto) else model
