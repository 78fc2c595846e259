#!/usr/bin/env python3
"""Fails when an integration test file would not be built.

A crate with `autotests = false` builds only the test targets its Cargo.toml lists: most
of its tests are modules of tests/suite.rs (one binary, one link), the rest are [[test]]
targets of their own. A file added to tests/ and named in neither would silently never run.
"""
import pathlib
import re
import sys
import tomllib

root = pathlib.Path(__file__).resolve().parent.parent
missing = []
for manifest in sorted(root.glob("crates/*/Cargo.toml")):
    cargo = tomllib.loads(manifest.read_text())
    if cargo["package"].get("autotests", True):
        continue
    tests = manifest.parent / "tests"
    targets = {(manifest.parent / t["path"]).resolve() for t in cargo.get("test", [])}
    suite = tests / "suite.rs"
    modules = set()
    if suite.resolve() in targets:
        modules = set(re.findall(r"^mod ([a-z0-9_]+);", suite.read_text(), re.M))
    for f in sorted(tests.glob("*.rs")):
        if f.resolve() not in targets and f.stem not in modules:
            missing.append(f.relative_to(root))
for f in missing:
    print(f"{f}: neither a module of tests/suite.rs nor a [[test]] of its Cargo.toml")
sys.exit(1 if missing else 0)
