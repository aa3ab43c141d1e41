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


def stubbed_callables():
    """(name, stub FunctionDef, runtime object) for every function, constructor and method of the stub."""
    for node in stub_tree().body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            yield node.name, node, getattr(cfl, node.name)
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            for item in node.body:
                is_property = any(getattr(d, "id", None) == "property" for d in item.decorator_list) \
                    if isinstance(item, ast.FunctionDef) else True
                if not is_property and (item.name == "__init__" or not item.name.startswith("_")):
                    yield f"{node.name}.{item.name}", item, getattr(getattr(cfl, node.name), item.name)


def test_stub_signatures_match_the_docstring_signatures():
    # Each docstring starts with the signature (pybind11's own would say "handle" for flexible arguments):
    # every argument of the stub appears there with a type, keyword-only ones after the "*".
    checked = 0
    for name, node, runtime in stubbed_callables():
        first_line = runtime.__doc__.lstrip().splitlines()[0]
        if name.endswith("__init__"):
            first_line = first_line.split("\n")[0]
        head, _, keyword_part = first_line.partition("*,")
        for arg in node.args.args:
            if arg.arg != "self" or "(self" in first_line:
                assert f"{arg.arg}: " in head or (arg.arg == "self" and "(self" in head), (name, arg.arg, first_line)
        for arg in node.args.kwonlyargs:
            assert f"{arg.arg}: " in keyword_part, (name, arg.arg, first_line)
        checked += 1
    assert checked >= 9


def test_help_explains_frames_and_units():
    text = cfl.distance.__doc__
    assert "world from a's frame" in text and "world frame" in text and "unit" in text
    assert "world from" in cfl.__doc__ and "unit" in cfl.__doc__


def test_help_describes_the_adaptive_regions():
    # The build options as the C++ builder now reads them (no uniform voxel grid picked from the mean edge
    # length, no padding about the center).
    model_doc = cfl.Model.__doc__ + cfl.Model.__init__.__doc__
    for phrase in ("adaptive", "uniform grid", "(padding - 1) / 2", "memory_limit", "coarsened", "leaves_per_depth",
                   "leaves_without_list"):
        assert phrase in model_doc, phrase
    for stale in ("voxel grid", "mean edge length", "about its center", "scaled by this factor"):
        assert stale not in model_doc and stale not in cfl.__doc__, stale
