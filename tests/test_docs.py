"""Documentation that is generated must stay current."""

from pathlib import Path

from nsfem.scene import SCHEMA, scene_reference

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_scene_reference_is_current():
    # regenerate with: python -m nsfem.scene > docs/scene.md
    assert (DOCS / "scene.md").read_text().strip() == scene_reference().strip()


def test_every_key_is_documented_with_a_default():
    text = (DOCS / "scene.md").read_text()
    for name, spec in SCHEMA.items():
        table = spec[0] if isinstance(spec, list) else spec
        if isinstance(table, dict):
            for key, k in table.items():
                assert f"| `{key}` |" in text, (name, key)
                assert k.doc
