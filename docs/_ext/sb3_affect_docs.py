"""
A directive that generates documentation from the code, so the pages can not drift from it:

* ``.. sweep-schema:: [forensics]`` (reStructuredText: in a Markdown page, inside an ``{eval-rst}`` block): the
  experiment-file reference, one table per section, from the pydantic models of ``sb3_affect.study.launcher.schema``
  (with ``forensics``: of ``sb3_affect.study.launcher.study_schema``, a forensics study file) (field names, types,
  defaults, constraints and descriptions);
"""

from __future__ import annotations

from typing import Any

from docutils import nodes
from docutils.parsers.rst import Directive
from docutils.statemachine import StringList

CONSTRAINTS = {
    "exclusiveMinimum": "> {}",
    "minimum": ">= {}",
    "minLength": "at least {} character(s)",
    "minItems": "at least {} item(s)",
    "pattern": "matches ``{}``",
}


def _type_name(annotation: Any) -> str:
    text = getattr(annotation, "__name__", None) if not getattr(annotation, "__args__", None) else None
    text = text or str(annotation).replace("typing.", "")
    for module in ("sb3_affect.study.launcher.schema.", "sb3_affect.study.launcher.study_schema."):
        text = text.replace(module, "")
    return text.replace("NoneType", "None")


def _constraints(schema: dict[str, Any]) -> list[str]:
    found = []
    for option in [schema, *schema.get("anyOf", [])]:
        for key, template in CONSTRAINTS.items():
            if key in option:
                found.append(template.format(option[key]))
    return found


class SweepSchema(Directive):
    """One table per section of an experiment file: top-level keys, ``env``, an item of ``agents`` (or a study's)."""

    optional_arguments = 1
    has_content = False

    def run(self) -> list[nodes.Node]:
        from pydantic_core import PydanticUndefined

        from sb3_affect.study.launcher.schema import AgentSpec, EnvSpec, MemberSpec, Sweep
        from sb3_affect.study.launcher.study_schema import ForensicsStudy, ProtocolSpec

        lines: list[str] = []
        sections: tuple[tuple[str, Any], ...] = (
            ("Top-level keys", Sweep),
            ("``env``", EnvSpec),
            ("Each item of ``agents``", AgentSpec),
            ("Each item of an agent's ``team``", MemberSpec),
        )
        if self.arguments == ["forensics"]:
            sections = (("Top-level keys of a forensics study file", ForensicsStudy), ("``protocol``", ProtocolSpec))
        for title, model in sections:
            properties = model.model_json_schema()["properties"]
            lines += [f".. rubric:: {title}", "", (model.__doc__ or "").strip().splitlines()[0], "",
                      ".. list-table::", "   :header-rows: 1", "   :widths: 14 18 16 52", "",
                      "   * - key", "     - type", "     - default", "     - meaning"]
            for name, field in model.model_fields.items():
                if field.is_required():
                    default = "required"
                elif field.default_factory is not None:
                    default = f"``{field.default_factory()!r}``".replace("EnvSpec(", "see ``env``").replace("``see", "see")
                    if "see ``env``" in default:
                        default = "see ``env``"
                    if "ProtocolSpec(" in default:
                        default = "the paper's (below)"
                elif field.default is PydanticUndefined:
                    default = "required"
                else:
                    default = f"``{field.default!r}``"
                extra = _constraints(properties.get(name, {}))
                meaning = (field.description or "") + (f" ({'; '.join(extra)})" if extra else "")
                lines += [f"   * - ``{name}``", f"     - ``{_type_name(field.annotation)}``", f"     - {default}",
                          f"     - {meaning}"]
            lines.append("")
        container = nodes.section()
        container.document = self.state.document
        self.state.nested_parse(StringList(lines, source="sb3_affect.study.launcher.schema"), self.content_offset, container)
        return list(container.children)


def setup(app: Any) -> dict[str, Any]:
    app.add_directive("sweep-schema", SweepSchema)
    return {"version": "1", "parallel_read_safe": True}
