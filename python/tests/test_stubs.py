"""The type stubs cover the native module: every public class, function and method of
`lagrangian._core` has a stub (so editors complete it), and every public callable has a
docstring (so they show it)."""

import ast
from pathlib import Path

import lagrangian
from lagrangian import _core

STUB = Path(lagrangian.__file__).with_name("_core.pyi")


def stubbed():
    tree = ast.parse(STUB.read_text(encoding="utf-8"))
    names, members = set(), {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            names.add(node.name)
            members[node.name] = {
                n.name if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) else n.target.id
                for n in node.body
                if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
                or (isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name))
            }
        elif isinstance(node, ast.FunctionDef):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return names, members


def test_every_public_name_has_a_stub():
    names, members = stubbed()
    public = {n for n in dir(_core) if not n.startswith("_")}
    assert public <= names, public - names
    for cls in ("Expr", "System", "CompiledRhs", "Solution", "EnsembleResult", "Event"):
        obj = getattr(_core, cls)
        own = {n for n in vars(obj) if not n.startswith("_")}
        assert own <= members[cls], (cls, own - members[cls])


def test_public_callables_have_docstrings():
    for cls in ("Expr", "System", "CompiledRhs", "Solution", "EnsembleResult", "Event"):
        obj = getattr(_core, cls)
        assert obj.__doc__, cls
        for n, v in vars(obj).items():
            if not n.startswith("_") and callable(v):
                assert v.__doc__, f"{cls}.{n}"
    assert _core.parse.__doc__ and _core.poisson.__doc__
