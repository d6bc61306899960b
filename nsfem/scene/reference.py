"""The Markdown reference of the scene keys (``python -m nsfem.scene > docs/scene.md``)."""

from __future__ import annotations

from typing import Any

from .schema import SCHEMA, SUPPORT_DOFS_BY_NAME, Key


STEP_TEXT = ("A stepped shaft: where a step covers x, its section (and material, if given) replaces `[shaft]`'s; "
             "keys it leaves out keep the shaft's, and its section kind is the shaft's. The mesh has a node at each "
             "step's ends (each piece of constant section is a segment, joined to the next one rigidly). Steps lie "
             "inside the shaft and may touch but not overlap; they cannot be combined with `[[delamination]]`.")


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
        nested = [(k, s[0]) for k, s in table.items() if isinstance(s, list)]
        for k, s in table.items():
            if isinstance(s, list):
                out.append(f"| `{k}` | `[]` | array of tables `[[{name}.{k}]]`, below |")
                continue
            doc = s.doc + (f"; one of {', '.join(f'`{c}`' for c in s.choices)}" if s.choices else "")
            out.append(f"| `{k}` | {_fmt(s.default)} | {doc} |")
        out.append("")
        for k, sub in nested:
            out += [f"### `[[{name}.{k}]]` (zero or more)", "", STEP_TEXT if (name, k) == ("shaft", "step") else "",
                    "", "| key | default | meaning |", "|---|---|---|"]
            out += [f"| `{j}` | {_fmt(t.default)} | {t.doc} |" for j, t in sub.items()]
            out.append("")
    out += ["## Supports", "", "| supports | fixed at x = 0 | fixed at x = L |", "|---|---|---|"]
    for k, (a, b) in SUPPORT_DOFS_BY_NAME.items():
        out.append(f"| `{k}` | {', '.join(a) or 'none'} | {', '.join(b) or 'none'} |")
    out += ["", "A prime marks a slope (V' = dV/dx). Where a delamination reaches a shaft end, the support",
            "holds each sub-beam.", "",
            "## Axes", "",
            "x is the shaft axis, y is horizontal and z vertical (up; gravity acts along -z). A bearing's",
            "`kxx` is therefore an axial (thrust) stiffness on U, and its lateral stiffness and damping are",
            "`kyy`, `kzz`, `kyz`, `kzy` and `cyy`, `czz`, `cyz`, `czy` (ROSS's horizontal x is our y, its",
            "vertical y our z). Keys in other axes (`cxx`, `kxy`, ...) are errors that say so. Write a thrust",
            "bearing as its own `[[bearing]]` with `kxx` alone.", "",
            "## Defaults that follow from the scene, and notes", "",
            "- `shaft.supports`: `\"pinned-pinned\"` for a shaft without bearings (the paper's); a rotor scene,",
            "  one with `[[bearing]]`, has no supports unless it gives the key (`\"free-free\"`: its bearings",
            "  hold it; supports are never added under bearings).",
            "- `section` left out: a circle when the table gives `diameter` (or `inner_diameter`) and neither",
            "  `width` nor `height`; else a rectangle.",
            "- `rho`: 7850 kg/m^3 (steel) for the shaft, segments and disks alike. The paper's delaminated",
            "  shaft (the shipped `default` scene) states its 7500.", "",
            "A scene is loaded with one-line notes for the defaults that shape a rotor's model without the",
            "scene saying so; every command that loads a scene prints each once on stderr",
            "(`nsfem run: note: ...`) and its JSON lists them under `notes` (`export` and `render` re-read",
            "the scene a run stored, whose notes that run printed). A scene that states these gets none",
            "(the shipped scenes get none). A rotor here is a scene with bearings, disks, unbalances, stators",
            "or cracks:", "",
            "| note | when | silenced by |", "|---|---|---|",
            "| `shaft: no section given` | a rotor's shaft (or segment) gives no section key (the paper's "
            "delaminated beams are its default square) | `section`, its size |",
            "| `beam.theory: euler-bernoulli by default` | a rotor without `[beam] theory`: the shaft has no "
            "rotary inertia or gyroscopic moments of its own (ROSS's elements have both) | `theory` |",
            "| `beam.theory: ... on a stubby rotor` | euler-bernoulli or rayleigh where a span between the places "
            "that hold the shaft (bearings, supports; else the whole shaft) is shorter than 10 section depths: "
            "shear deformation is left out | `theory = \"timoshenko\"` |",
            "| `disk.<i>: given by its mass, its polar_inertia ... is 0` | a disk with `mass` and without an inertia: "
            "a point mass, no gyroscopic moment or rotary inertia | `polar_inertia`, `diametral_inertia` (0 if "
            "meant), or the geometry |",
            "| `bearing.<i>: kxx = ... with kyy and no kzz` / `as large as its lateral ...` | a bearing with `kxx` "
            "beside `kyy` and no `kzz` (ROSS's axes), or `kxx` at least its smaller lateral stiffness | the "
            "thrust bearing as its own `[[bearing]]` |",
            "no bearing has `kxx` (a 0 Hz axial mode; `stationary` has no solution) | a `kxx`, or `supports` "
            "holding U |",
            "where fewer than two places hold y (supports fixing V, bearings with `kyy`; a clamp and one place do) "
            "or z likewise (dampers hold nothing at rest) | `kyy`, `kzz`, or `supports` |", ""]
    return "\n".join(out)
