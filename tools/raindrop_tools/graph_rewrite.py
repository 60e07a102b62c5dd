"""Rewriting a committed model folder's graphs in place, checked: the tools that change how a
graph computes, not what (phase_conv.py, inner_padding.py, phase_final_conv.py), share this,
and the small graph queries they all make.

Each graph is transformed, checked by ONNX's checker, and compared with the old graph by ONNX
Runtime on random inputs of the sizes given; only when all three graphs pass do they and
export.json (digests updated, a note added) replace the old files, through a staging folder
(staging.py). Imports without torch.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import onnx

from . import contract as C
from .staging import staged_model_files


class GraphRewriteError(ValueError):
    pass


def attrs(node: onnx.NodeProto) -> dict:
    """A node's attributes by name, as Python values."""
    return {a.name: onnx.helper.get_attribute_value(a) for a in node.attribute}


def only_consumer(consumers: dict[str, list[onnx.NodeProto]], tensor: str, op: str | None = None) -> onnx.NodeProto | None:
    """The one node that reads ``tensor`` (of type ``op``, if given), or None."""
    c = consumers.get(tensor, [])
    return c[0] if len(c) == 1 and (op is None or c[0].op_type == op) else None


def consumers(model: onnx.ModelProto) -> dict[str, list[onnx.NodeProto]]:
    """For each tensor name, the nodes that read it, in graph order."""
    out: dict[str, list[onnx.NodeProto]] = {}
    for n in model.graph.node:
        for i in n.input:
            out.setdefault(i, []).append(n)
    return out


def prune(model: onnx.ModelProto) -> None:
    """Removes nodes whose outputs nothing reads (repeatedly), then initializers and value_info
    entries that no longer name a tensor of the graph."""
    g = model.graph
    outputs = {o.name for o in g.output}
    while True:
        used = outputs | {i for n in g.node for i in n.input}
        kept = [n for n in g.node if any(o in used for o in n.output)]
        if len(kept) == len(g.node):
            break
        del g.node[:]
        g.node.extend(kept)
    used = outputs | {i for n in g.node for i in n.input}
    inits = [t for t in g.initializer if t.name in used]
    del g.initializer[:]
    g.initializer.extend(inits)
    produced = {o for n in g.node for o in n.output}
    infos = [v for v in g.value_info if v.name in produced]
    del g.value_info[:]
    g.value_info.extend(infos)


def topological_sort(model: onnx.ModelProto) -> None:
    """Puts the graph's nodes in an order where every input is produced before it is read
    (ONNX requires it; a rewrite that moves a node may break the old order)."""
    g = model.graph
    ready = {i.name for i in g.input} | {t.name for t in g.initializer} | {""}
    pending, ordered = list(g.node), []
    while pending:
        progress = [n for n in pending if all(i in ready for i in n.input)]
        if not progress:
            raise GraphRewriteError("the rewritten graph has a cycle or reads a tensor nothing produces")
        for n in progress:
            ready.update(n.output)
        ordered += progress
        pending = [n for n in pending if n not in progress]
    del g.node[:]
    g.node.extend(ordered)


def rewrite_folder(models_dir: Path, tag: str, transform: Callable[[onnx.ModelProto], int],
                   sizes: tuple[tuple[int, int], ...], max_abs_diff: float, note: str,
                   error: type[GraphRewriteError] = GraphRewriteError) -> dict[str, int]:
    """Applies ``transform`` (which changes a graph in place and returns how many places it
    changed) to the folder's three graphs; each changed graph must give the old one's outputs to
    ``max_abs_diff`` at every (H, W) of ``sizes``. export.json gets the new digests and
    ``note`` under ``tag``. A graph the transform left alone keeps its bytes, and a folder where
    nothing changed is not touched at all. Returns the count per graph; raises ``error``."""
    import onnxruntime as ort

    models_dir = Path(models_dir)
    models = {name: onnx.load(str(models_dir / C.FILES[name])) for name in C.NETWORKS}
    counts = {name: transform(model) for name, model in models.items()}
    if not any(counts.values()):
        return counts
    with staged_model_files(models_dir, tag) as stage:
        rng = np.random.default_rng(0)
        so = ort.SessionOptions()
        so.log_severity_level = 3
        for name, model in models.items():
            src, staged = models_dir / C.FILES[name], stage / C.FILES[name]
            if not counts[name]:
                staged.write_bytes(src.read_bytes())
                continue
            onnx.checker.check_model(model)
            onnx.save(model, str(staged))
            old = ort.InferenceSession(str(src), so, providers=["CPUExecutionProvider"])
            new = ort.InferenceSession(str(staged), so, providers=["CPUExecutionProvider"])
            for h, w in sizes:
                feed = {i.name: rng.random((1, i.shape[1], h, w), dtype=np.float32) for i in old.get_inputs()}
                want, got = old.run(None, feed)[0], new.run(None, feed)[0]
                diff = float(np.abs(want - got).max()) if want.shape == got.shape else float("inf")
                if not diff <= max_abs_diff:
                    raise error(f"{src}: the rewritten graph differs from the old one by {diff:g} > "
                                f"{max_abs_diff} at {h}x{w}")
        info_file = models_dir / C.EXPORT_INFO
        if info_file.is_file():
            info = json.loads(info_file.read_text())
            info["files"] = C.graph_files(stage)
            info[tag.replace("-", "_")] = note
            (stage / C.EXPORT_INFO).write_text(json.dumps(info, indent=2) + "\n")
    return counts


def command(prog: str, description: str, rewrite: Callable[[Path], dict[str, int]], done: str,
            argv: list[str] | None) -> int:
    """The command line of a folder rewrite: ``--models DIR`` (repeatable), one line per folder
    (the counts per graph, then ``done``), a one-line error and exit 2 on failure."""
    ap = argparse.ArgumentParser(prog=f"python -m raindrop_tools.{prog}", description=description)
    ap.add_argument("--models", required=True, action="append", help="model folder to rewrite in place (repeatable)")
    args = ap.parse_args(argv)
    for d in args.models:
        try:
            counts = rewrite(Path(d))
        # (ONNX Runtime's load and run errors are RuntimeErrors; a graph the transforms do not
        # expect may raise KeyError or ValueError from onnx.)
        except (GraphRewriteError, OSError, onnx.checker.ValidationError, KeyError, ValueError, RuntimeError) as e:
            print(f"{prog}: error: {e}", file=sys.stderr)
            return 2
        print(f"{prog}: {d}: " + ", ".join(f"{n} {c}" for n, c in counts.items()) + " " + done)
    return 0
