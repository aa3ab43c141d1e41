"""The typing stub describes the module as built: the same names, members and keyword arguments."""

import ast
import inspect
import os

import cfl

STUB = os.path.join(os.path.dirname(os.path.abspath(cfl.__file__)), "__init__.pyi")


def stub_tree():
    with open(STUB) as f:
        return ast.parse(f.read())


def public(names):
    return {n for n in names if not n.startswith("_")}


def test_stub_is_installed_beside_the_module():
    assert os.path.exists(STUB)
    assert os.path.exists(os.path.join(os.path.dirname(STUB), "py.typed"))


def test_stub_names_every_public_class_and_function():
    tree = stub_tree()
    stubbed = public(node.name for node in tree.body if isinstance(node, (ast.ClassDef, ast.FunctionDef)))
    assert stubbed == set(cfl.__all__)


def test_stub_classes_list_the_real_members():
    for node in stub_tree().body:
        if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            stubbed = public(item.name for item in node.body if isinstance(item, ast.FunctionDef))
            real = public(name for name in dir(getattr(cfl, node.name)))
            assert stubbed == real - {"__init__"} - {"__getstate__", "__setstate__"}, node.name


def test_stub_functions_take_the_documented_keywords():
    # pybind11 puts the signature on the first docstring line: compare argument names with the stub's.
    for node in stub_tree().body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            args = [a.arg for a in node.args.args + node.args.kwonlyargs]
            first_line = getattr(cfl, node.name).__doc__.splitlines()[0]
            for name in args:
                assert f"{name}: " in first_line, (node.name, name)


def test_help_explains_frames_and_units():
    text = cfl.distance.__doc__
    assert "world from a's frame" in text and "world frame" in text and "unit" in text
    assert "world from" in cfl.__doc__ and "unit" in cfl.__doc__
