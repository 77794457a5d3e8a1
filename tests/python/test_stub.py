"""The type stubs (rodfit/__init__.pyi) describe the package as it is: the same public names,
and the Runtime's methods."""
import ast
import pathlib

import rodfit


def _stub():
    return ast.parse((pathlib.Path(rodfit.__file__).parent / "__init__.pyi").read_text())


def test_stub_names_are_the_public_api():
    tree = _stub()
    names = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    public = set(rodfit.__all__) - {"__version__"}
    assert names == public


def test_stub_runtime_methods_exist():
    runtime = next(n for n in _stub().body if isinstance(n, ast.ClassDef) and n.name == "Runtime")
    methods = {f.name for f in runtime.body if isinstance(f, ast.FunctionDef)} - {"__init__"}
    assert methods and all(hasattr(rodfit.Runtime, m) for m in methods), methods
