"""The package's layering: evaluation and the command line sit on top, nothing below imports them."""
import ast
from pathlib import Path

import symtorch

PKG = Path(symtorch.__file__).parent


def _imports(path: Path) -> set[str]:
    """Absolute names of the symtorch modules one file imports (relative imports resolved)."""
    mod = ["symtorch", *path.relative_to(PKG).with_suffix("").parts]
    pkg = mod if path.name == "__init__.py" else mod[:-1]
    if path.name == "__init__.py":
        pkg = mod[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - node.level + 1]
                out.add(".".join(base + ([node.module] if node.module else [])))
            elif node.module and node.module.startswith("symtorch"):
                out.add(node.module)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("symtorch"))
    return out


def _layer(name: str) -> str:
    parts = name.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in ("eval", "cli") else "core"


def test_lower_layers_do_not_import_eval_or_cli():
    offenders = []
    for path in PKG.rglob("*.py"):
        rel = path.relative_to(PKG)
        if rel.parts[0] in ("eval", "cli") or rel.name == "__main__.py":
            continue
        for name in _imports(path):
            if _layer(name) != "core":
                offenders.append(f"{rel} imports {name}")
    assert not offenders, offenders


def test_eval_does_not_import_cli():
    offenders = [f"{p.relative_to(PKG)} imports {n}" for p in (PKG / "eval").rglob("*.py")
                 for n in _imports(p) if _layer(n) == "cli"]
    assert not offenders, offenders


def test_the_layering_check_sees_relative_imports(tmp_path):
    # the check itself must resolve ``from ..eval import x`` inside a sub-package
    probe = PKG / "detect" / "auto.py"
    names = _imports(probe)
    assert any(n.startswith("symtorch.detect.") for n in names), names
    assert "symtorch.spectrum" in names or "symtorch.geodesics" in names, names
