"""The user-facing docs name files that exist: a command copied from them must not fail on a
config, scene, script or document that was renamed or removed since (tools/README.md's
fine-tuning command named tools/configs/compact-mix.yaml for months after it became
compact-real.yaml)."""

import re

from helpers import REPO

# The documents a user follows; docs/RESULTS.md is a log and may name what is gone.
DOCS = ["README.md", "tools/README.md", "docs/SCENES.md", "docs/CONTRACTS.md", "docs/DESIGN.md", "models/README.md"]
# Paths under these folders must exist where a document names them (models/ is left out: its
# examples name output folders a command creates).
PATH = re.compile(r"(?<![\w/.-])((?:tools/configs|tools/raindrop_tools|scenes|scripts|docs)/[\w.-]+(?:/[\w.-]+)*)")
# python -m raindrop_tools.<module>
MODULE = re.compile(r"python -m raindrop_tools\.(\w+)")


def named_paths(text: str) -> set[str]:
    return {m.rstrip(".") for m in PATH.findall(text)}


def test_every_path_the_docs_name_exists():
    missing = []
    for doc in DOCS:
        text = (REPO / doc).read_text(encoding="utf-8")
        missing += [f"{doc}: {p}" for p in sorted(named_paths(text)) if not (REPO / p).exists()]
        missing += [
            f"{doc}: python -m raindrop_tools.{m}"
            for m in sorted(set(MODULE.findall(text)))
            if not (REPO / "tools" / "raindrop_tools" / f"{m}.py").exists()
        ]
    assert not missing, "the docs name files that do not exist:\n" + "\n".join(missing)


def test_the_pattern_finds_paths_and_skips_placeholders():
    text = (
        "run `python -m raindrop_tools.train --config tools/configs/compact-mix.yaml` then see "
        "docs/RESULTS.md. Scenes: scenes/paper.json, scenes/<name>.json; build/raindrop-render."
    )
    assert named_paths(text) == {"tools/configs/compact-mix.yaml", "docs/RESULTS.md", "scenes/paper.json"}
    assert MODULE.findall(text) == ["train"]
