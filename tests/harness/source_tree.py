"""The project's source, listed, read and parsed once per test process (a pytest session, or one
xdist worker) for every house-rule test that checks it: layering, the CLI layer, the closing
pair, the single-definition rules. Parsing the tree is most of what those tests cost; each used
to walk and parse it again (one took 9.5 s of the fast tier).

The trees and nodes are shared between tests: read them, never change them. They live until the
process ends, outside the garbage collector's reach (`gc.freeze`).
"""

from __future__ import annotations

import ast
import gc
from functools import cache
from pathlib import Path


@cache
def python_files(folder: Path) -> tuple[Path, ...]:
    """Every .py file below `folder`, sorted."""
    return tuple(sorted(folder.rglob("*.py")))


@cache
def text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


@cache
def tree(path: Path) -> ast.Module:
    parsed = ast.parse(text(path))
    # Kept for the whole session, hundreds of thousands of nodes would make every full garbage
    # collection after this one walk them all (pytest collects between tests): frozen, the
    # collector leaves them be.
    gc.freeze()
    return parsed


@cache
def nodes(path: Path) -> tuple[ast.AST, ...]:
    """Every node of the file's tree, in `ast.walk` order."""
    return tuple(ast.walk(tree(path)))


@cache
def docstrings(path: Path) -> frozenset[int]:
    """The ids of the file's docstring constants (module, class, function): what a rule on
    string constants leaves out, since a docstring may quote anything."""
    return frozenset(id(n.body[0].value) for n in nodes(path)
                     if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef,
                                       ast.AsyncFunctionDef))
                     and n.body and isinstance(n.body[0], ast.Expr)
                     and isinstance(n.body[0].value, ast.Constant))
