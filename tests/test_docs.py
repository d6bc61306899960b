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
                for sub, j in (k[0].items() if isinstance(k, list) else [(key, k)]):   # [[shaft.step]]'s keys
                    assert f"| `{sub}` |" in text, (name, key, sub)
                    assert j.doc
