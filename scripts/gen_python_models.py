#!/usr/bin/env python3
"""Generates the Python client's pydantic models (sdk/python/rtcnc/models.py) from the
OpenAPI document (docs/openapi.json), so that the schemas are written once, in the server's
code. Run it after regenerating docs/openapi.json; sdk/python/tests checks that the
committed models are current.

    python3 scripts/gen_python_models.py [--check]
"""

import json
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "openapi.json"
OUT = ROOT / "sdk" / "python" / "rtcnc" / "models.py"

SCALARS = {"string": "str", "integer": "int", "number": "float", "boolean": "bool"}


def ref_name(ref: str) -> str:
    return ref.rsplit("/", 1)[-1]


def type_of(schema: dict) -> tuple[str, bool]:
    """The Python type of a schema and whether it admits null."""
    if "$ref" in schema:
        return ref_name(schema["$ref"]), False
    for key in ("oneOf", "anyOf"):
        if key in schema:
            nullable = False
            types = []
            for option in schema[key]:
                if option.get("type") == "null":
                    nullable = True
                else:
                    t, n = type_of(option)
                    nullable |= n
                    types.append(t)
            return (" | ".join(types) if types else "Any"), nullable
    t = schema.get("type")
    nullable = False
    if isinstance(t, list):
        nullable = "null" in t
        rest = [x for x in t if x != "null"]
        t = rest[0] if len(rest) == 1 else None
    if t in SCALARS:
        return SCALARS[t], nullable
    if t == "array":
        items = schema.get("items") or {}
        inner, inner_null = type_of(items) if items else ("Any", False)
        if inner_null:
            inner = f"{inner} | None"
        return f"list[{inner}]", nullable
    if t == "object" or t is None:
        extra = schema.get("additionalProperties")
        if isinstance(extra, dict):
            inner, _ = type_of(extra)
            return f"dict[str, {inner}]", nullable
        return "dict[str, Any]", nullable
    return "Any", nullable


def docstring(text: str, indent: str) -> list[str]:
    text = " ".join(text.split()).replace('"""', "'''")
    return [f'{indent}"""{text}"""'] if text else []


def generate(doc: dict) -> str:
    schemas = doc["components"]["schemas"]
    lines = [
        '"""Models of the rtcnc API, generated from docs/openapi.json by',
        "scripts/gen_python_models.py. Do not edit: regenerate.\"\"\"",
        "",
        "from __future__ import annotations",
        "",
        "from typing import Any",
        "",
        "from pydantic import BaseModel, ConfigDict, Field",
        "",
        f'API_VERSION = "{doc["info"]["version"]}"',
        "",
    ]
    classes = []
    for name in sorted(schemas):
        s = schemas[name]
        if s.get("type") == "object" and "properties" in s:
            classes.append(name)
            lines += ["", f"class {name}(BaseModel):"]
            lines += docstring(s.get("description", ""), "    ")
            lines.append('    model_config = ConfigDict(extra="allow", populate_by_name=True)')
            lines.append("")
            required = set(s.get("required", []))
            for prop in sorted(s["properties"]):
                p = s["properties"][prop]
                t, nullable = type_of(p)
                field = prop
                alias = ""
                if prop in ("type",) or not prop.isidentifier():
                    field = prop.rstrip("_") + "_"
                    alias = f'alias="{prop}"'
                optional = nullable or prop not in required
                if optional:
                    t = f"{t} | None"
                desc = " ".join(p.get("description", "").split()).replace('"', "'")
                args = []
                if optional:
                    args.append("default=None")
                if alias:
                    args.append(alias)
                if desc:
                    args.append(f'description="{desc}"')
                lines.append(f"    {field}: {t} = Field({', '.join(args)})")
        else:
            t, _ = type_of(s)
            lines += ["", f"{name} = {t}"]
            lines += docstring(s.get("description", ""), "")
    lines.append("")
    lines += [f"{c}.model_rebuild()" for c in classes]
    return "\n".join(lines) + "\n"


def main() -> int:
    text = generate(json.loads(DOC.read_text()))
    if "--check" in sys.argv:
        if OUT.read_text() != text:
            print(f"{OUT} is stale: run scripts/gen_python_models.py", file=sys.stderr)
            return 1
        return 0
    OUT.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
