"""Every public function and method carries type hints: each parameter (but a method's
``self`` / ``cls``) and its return.

Read from the source with `ast`, so no module is imported (the Blender side's need bpy).
Every module of the package is read. "Public": a module-level function, or a method of a module-level class, whose name does not
start with "_" (dunder methods such as ``__init__`` and ``__call__`` count), in a module and
class whose names do not start with "_" either. Functions inside ``if`` / ``try`` blocks at
module or class level (an ``if TYPE_CHECKING:`` protocol) count too; functions nested in a
function are that function's own and do not.
"""

from __future__ import annotations

import ast
import pathlib

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "keyframe_implicit"


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _missing(function: ast.FunctionDef | ast.AsyncFunctionDef, method: bool) -> list[str]:
    """The parameters of ``function`` without a hint ("*args" for a star parameter), and
    "return" when its return has none; a method's first parameter needs none, unless it
    is a static method."""
    args = function.args
    params = args.posonlyargs + args.args + args.kwonlyargs
    static = any(isinstance(d, ast.Name) and d.id == "staticmethod"
                 for d in function.decorator_list)
    if method and not static and args.posonlyargs + args.args:
        params = params[1:]
    missing = [p.arg for p in params if p.annotation is None]
    missing += [f"{stars}{p.arg}" for stars, p in (("*", args.vararg), ("**", args.kwarg))
                if p is not None and p.annotation is None]
    if function.returns is None:
        missing.append("return")
    return missing


def unannotated(source: str, module: str) -> list[str]:
    """``module:qualified.name (what)`` of every public function of ``source`` missing a hint."""
    found = []

    def visit(body: list[ast.stmt], prefix: str, in_class: bool) -> None:
        for node in body:
            if isinstance(node, ast.ClassDef):
                if not _private(node.name):
                    visit(node.body, f"{prefix}{node.name}.", True)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                missing = _missing(node, in_class)
                if missing and not _private(node.name):
                    found.append(f"{module}:{prefix}{node.name} ({', '.join(missing)})")
            elif isinstance(node, ast.If):
                visit(node.body + node.orelse, prefix, in_class)
            elif isinstance(node, ast.Try):
                visit(node.body + node.orelse + node.finalbody
                      + [s for h in node.handlers for s in h.body], prefix, in_class)

    visit(ast.parse(source).body, "", False)
    return found


def test_public_functions_have_type_hints():
    modules = sorted(PACKAGE.rglob("*.py"))
    assert len(modules) > 80, f"only {len(modules)} modules found under {PACKAGE}"
    found = []
    for path in modules:
        name = path.relative_to(PACKAGE).with_suffix("").as_posix()
        if any(_private(part) for part in name.split("/")):
            continue
        found += unannotated(path.read_text(encoding="utf-8"),
                             "keyframe_implicit." + name.replace("/", "."))
    assert not found, "public functions without type hints:\n" + "\n".join(found)


def test_the_check_sees_each_missing_hint():
    source = '''
def whole(a: int, *rest: int, b: str = "", **more: float) -> None: ...
def no_return(a: int): ...
def bare(a, b: int) -> int: ...
def stars(*args, **kwargs) -> None: ...
def _helper(a): ...
class Public:
    def __init__(self, size): ...
    def __call__(self, x: float) -> float: ...
    @classmethod
    def make(cls) -> "Public": ...
    @staticmethod
    def still(self) -> None: ...
    def _own(self, x): ...
    class Inner:
        def deep(self, y) -> None: ...
class _Private:
    def method(self, x): ...
if True:
    def guarded(x) -> None: ...
def outer() -> None:
    def nested(x): ...
'''
    assert unannotated(source, "m") == [
        "m:no_return (return)",
        "m:bare (a)",
        "m:stars (*args, **kwargs)",
        "m:Public.__init__ (size, return)",
        "m:Public.still (self)",
        "m:Public.Inner.deep (y)",
        "m:guarded (x)",
    ]
