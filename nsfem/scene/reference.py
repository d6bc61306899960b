"""The Markdown reference of the scene keys (``python -m nsfem.scene > docs/scene.md``)."""

from __future__ import annotations

from typing import Any

from .schema import SCHEMA, SUPPORT_DOFS_BY_NAME, Key


def _fmt(v: Any) -> str:
    if v is None:
        return "(see text)"
    if isinstance(v, str):
        return f'`"{v}"`' if v else '`""`'
    if isinstance(v, bool):
        return f"`{str(v).lower()}`"
    return f"`{v}`"


def scene_reference() -> str:
    """Markdown reference of every scene key with its default (``docs/scene.md``)."""
    out = ["# Scene reference", "",
           "Generated from `nsfem.scene.SCHEMA` by `python -m nsfem.scene > docs/scene.md`; a test keeps it",
           "current. Units are SI. Keys left out take the default shown; unknown keys are errors.",
           "A scene uses either the high-level tables (`[shaft]`, `[[delamination]]`, `[[obstacle]]`)",
           "or the low-level ones (`[[segment]]`, `[[junction]]`, `[[support]]`, `[[contact]]`); the",
           "other tables apply to both. Override any key from the command line with",
           "`--set table.key=VALUE` (list items by index: `--set delamination.0.friction=0.3`; an index",
           "one past the end appends an item).", ""]
    for name, spec in SCHEMA.items():
        if isinstance(spec, Key):
            out += [f"## `{name}`", "", f"{spec.doc}. Default {_fmt(spec.default)}.", ""]
            continue
        table, array = (spec[0], True) if isinstance(spec, list) else (spec, False)
        out += [f"## `[[{name}]]` (zero or more)" if array else f"## `[{name}]`", "",
                "| key | default | meaning |", "|---|---|---|"]
        for k, s in table.items():
            doc = s.doc + (f"; one of {', '.join(f'`{c}`' for c in s.choices)}" if s.choices else "")
            out.append(f"| `{k}` | {_fmt(s.default)} | {doc} |")
        out.append("")
    out += ["## Supports", "", "| supports | fixed at x = 0 | fixed at x = L |", "|---|---|---|"]
    for k, (a, b) in SUPPORT_DOFS_BY_NAME.items():
        out.append(f"| `{k}` | {', '.join(a) or 'none'} | {', '.join(b) or 'none'} |")
    out += ["", "A prime marks a slope (V' = dV/dx). Where a delamination reaches a shaft end, the support",
            "holds each sub-beam.", ""]
    return "\n".join(out)
