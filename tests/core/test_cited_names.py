"""Every name, path and command that benchmarks/README.md and docs/method.md cite exists.

Both documents send the reader to the code: a rename or a move that leaves them behind
makes them point at nothing. Each span in backticks is read as one of:

- a command: ``python benchmarks/<script>.py ...``, ``python -m keyframe_implicit ...`` or
  ``scripts/<name> ...``. The script (or package) exists and every ``--option`` is one it
  declares (a string constant of its code);
- a path: no space, and a ``/`` or a file suffix. It names a file or folder from the
  repository's root, ``keyframe_implicit/``, ``keyframe_implicit/core/`` (the method
  notes' convention) or ``benchmarks/``; a bare file name (``rbf.py``) is a file of that
  name anywhere in the project's folders;
- a Python reference: a name, a dotted name, ``name=value``, a call or a subscript.
  - A bare name is defined (function, class, parameter, module- or class-level
    assignment, dataclass field, ``self.x =``), imported, or a string constant of the code
    (an option or property read by its name, ``"volume_weight"``).
  - A dotted name is the tail of a defined name's path (``system.HESSIAN_DTYPE``,
    ``MapOptions.margin_cells``), an attribute of an installed module
    (``scipy.interpolate.RBFInterpolator``), or an attribute some class defines, read off
    a parameter (``batch.weight``).
  - A call's keywords are parameters or fields of what it calls, and a string value is a
    string constant of the code (``transport="two-sided"``).

Not checked: numbers, formulas (any operator), spans that are not Python, anything with
symbols beyond ASCII, the letters of the mathematics (``h``, ``ij``, ``A_ij``), a
how-to's placeholders (``my_term``) and names in Blender's own modules (``bpy``), which
do not import outside Blender. Definitions are read with `ast` from
keyframe_implicit/, benchmarks/, scripts/ and the test suite's helper modules (not its
test files), so a name kept alive only by a test does not count.
"""

import ast
import builtins
import dataclasses
import importlib
import importlib.util
import inspect
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGE = "keyframe_implicit"
DOCUMENTS = ("benchmarks/README.md", "docs/method.md")
#: Folders a relative path may start from, in the order tried.
PATH_ROOTS = ("", PACKAGE, f"{PACKAGE}/core", "benchmarks")
#: Folders whose files a bare file name may name.
FILE_FOLDERS = (PACKAGE, "benchmarks", "scripts", "tests", "docs", "assets")
FILE_NAME = re.compile(r"^[\w.-]+\.(py|md|sh|png|json|csv|blend|toml|txt|yaml|zip)$")
PATH = re.compile(r"^[\w.-]+(/[\w.-]+)*/?$")
WORD = re.compile(r"^[A-Za-z_][\w.-]+$")
#: One letter, with one more or an index (``ij``, ``f0``, ``A_ij``, ``x_A``).
MATH_NAME = re.compile(r"^[A-Za-z](_[A-Za-z0-9]{1,3}|[A-Za-z0-9])?$")
#: Modules that exist only inside Blender.
BLENDER_MODULES = {"bpy", "bpy_extras", "bmesh", "mathutils", "gpu", "gpu_extras", "openvdb"}
KEYWORD_VALUE = re.compile(r"^([A-Za-z_]\w*)=(.+)$")
#: Nodes a Python reference may hold; any other makes the span a formula.
REFERENCE_NODES = (ast.Expression, ast.Name, ast.Attribute, ast.Call, ast.keyword,
                   ast.Constant, ast.Subscript, ast.Tuple, ast.Load)


@dataclasses.dataclass
class Definitions:
    """What the code defines, read from its source."""

    #: every name defined, imported or a parameter
    bare: set = dataclasses.field(default_factory=set)
    #: every dotted tail (two parts or more) of a defined name's path
    dotted: set = dataclasses.field(default_factory=set)
    #: {dotted tail of a callable: its parameters (a class: __init__'s and its fields)}
    parameters: dict = dataclasses.field(default_factory=dict)
    #: every string constant of the code but docstrings
    strings: set = dataclasses.field(default_factory=set)
    #: every parameter's name: what a dotted name may be read off (``batch.weight``)
    variables: set = dataclasses.field(default_factory=set)
    #: every module's, package's and class's name
    scopes: set = dataclasses.field(default_factory=set)

    def add(self, scope: tuple, name: str) -> None:
        """``name`` defined in ``scope`` (the module's path parts, then its classes)."""
        self.bare.add(name)
        qualified = (*scope, name)
        self.dotted.update(".".join(qualified[start:]) for start in range(len(qualified) - 1))

    def add_parameters(self, scope: tuple, name: str, names: set) -> None:
        """The parameters ``names`` of the callable ``name`` defined in ``scope``."""
        qualified = (*scope, name)
        for start in range(len(qualified)):
            self.parameters.setdefault(".".join(qualified[start:]), set()).update(names)
        self.bare.update(names)
        self.variables.update(names)


def _parameter_names(function: ast.FunctionDef) -> set:
    arguments = function.args
    every = [*arguments.posonlyargs, *arguments.args, *arguments.kwonlyargs]
    return {a.arg for a in every} - {"self", "cls"}


def _target_names(target: ast.expr) -> list:
    if isinstance(target, ast.Name):
        return [target.id]
    if isinstance(target, (ast.Tuple, ast.List)):
        return [n for element in target.elts for n in _target_names(element)]
    return []


def _read_function(definitions: Definitions, scope: tuple, function: ast.FunctionDef,
                   owner: tuple | None) -> None:
    """A function's name and parameters, its nested functions', and in a method of the
    class ``owner`` the attributes it sets on ``self``."""
    definitions.add(scope, function.name)
    definitions.add_parameters(scope, function.name, _parameter_names(function))
    for node in ast.walk(function):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node is not function:
            definitions.add_parameters((), node.name, _parameter_names(node))
        if owner is None or not isinstance(node, (ast.Assign, ast.AnnAssign)):
            continue
        for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
            if (isinstance(target, ast.Attribute) and isinstance(target.value, ast.Name)
                    and target.value.id in ("self", "cls")):
                definitions.add(owner, target.attr)


def _read_class(definitions: Definitions, scope: tuple, node: ast.ClassDef) -> None:
    definitions.add(scope, node.name)
    definitions.scopes.add(node.name)
    inner = (*scope, node.name)
    _read_body(definitions, inner, node.body, owner=inner)
    fields = {n.target.id for n in node.body
              if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)}
    init = [n for n in node.body if isinstance(n, ast.FunctionDef) and n.name == "__init__"]
    definitions.add_parameters(scope, node.name,
                               fields | (_parameter_names(init[0]) if init else set()))


def _read_body(definitions: Definitions, scope: tuple, body: list,
               owner: tuple | None = None) -> None:
    """The names a module's or a class's statements define."""
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            _read_function(definitions, scope, node, owner)
        elif isinstance(node, ast.ClassDef):
            _read_class(definitions, scope, node)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                for name in _target_names(target):
                    definitions.add(scope, name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)) and owner is None:
            for alias in node.names:  # a package's re-export: `core.animate`
                name = (alias.asname or alias.name).split(".")[0]
                definitions.dotted.update(".".join((*scope, name)[start:])
                                          for start in range(len(scope)))
        elif isinstance(node, (ast.If, ast.Try, ast.With)):
            for block in ("body", "orelse", "finalbody"):
                _read_body(definitions, scope, getattr(node, block, []), owner)
            for handler in getattr(node, "handlers", []):
                _read_body(definitions, scope, handler.body, owner)


def _string_constants(tree: ast.AST) -> set:
    """The string constants of a module, its docstrings left out."""
    docstrings = {id(node.value) for node in ast.walk(tree) if isinstance(node, ast.Expr)}
    return {node.value for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str)
            and id(node) not in docstrings}


def _sources() -> list:
    folders = [ROOT / PACKAGE, ROOT / "benchmarks", ROOT / "scripts"]
    files = [p for folder in folders for p in folder.rglob("*.py")]
    files += [p for p in (ROOT / "tests").rglob("*.py") if not p.name.startswith("test_")]
    return sorted(files)


def read_definitions(files: list | None = None) -> Definitions:
    """`Definitions` of the given source files (all the project's by default)."""
    definitions = Definitions()
    for path in files or _sources():
        parts = path.relative_to(ROOT).with_suffix("").parts
        scope = parts[:-1] if parts[-1] == "__init__" else parts
        definitions.dotted.update(".".join(scope[start:]) for start in range(len(scope)))
        definitions.bare.update(scope)  # modules and packages are names too
        definitions.scopes.update(scope)
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        _read_body(definitions, scope, tree.body)
        definitions.bare.update((alias.asname or alias.name).split(".")[0]
                                for node in ast.walk(tree)
                                if isinstance(node, (ast.Import, ast.ImportFrom))
                                for alias in node.names)
        definitions.strings.update(_string_constants(tree))
    return definitions


def cited_spans(text: str) -> list:
    """The spans in backticks of a markdown text, fenced code blocks left out."""
    text = re.sub(r"^\s*```.*?^\s*```", "", text, flags=re.S | re.M)
    return [" ".join(span.split()) for span in re.findall(r"`([^`]+)`", text)]


def _not_checked(name: str) -> bool:
    """A letter of the mathematics (``h``, ``ij``, ``A_ij``) or a placeholder (``my_term``)."""
    return bool(MATH_NAME.match(name)) or name == "my" or name.startswith("my_")


def check_command(words: list, definitions: Definitions) -> list | None:
    """Problems of a command line, or None when it is not one of the project's."""
    if words[0] == "python":
        words = words[1:]
    if len(words) > 1 and words[0] == "-m":
        command, options, known = words[1], words[2:], definitions.strings
        if not (ROOT / command.replace(".", "/") / "__main__.py").is_file():
            return [f"no package {command} with a __main__"]
    elif words and words[0].endswith(".py"):
        command, options = words[0], words[1:]
        script = next((ROOT / base / command for base in PATH_ROOTS
                       if (ROOT / base / command).is_file()), None)
        if script is None:
            return [f"no script {command}"]
        known = _string_constants(ast.parse(script.read_text(encoding="utf-8")))
    elif words and words[0].startswith("scripts/"):
        return [] if (ROOT / words[0]).is_file() else [f"no script {words[0]}"]
    else:
        return None
    flags = [w.strip("[]").split("=")[0] for w in options if w.strip("[]").startswith("--")]
    return [f"{command} has no option {flag}" for flag in flags if flag not in known]


def _is_path(span: str) -> bool:
    if not PATH.match(span) or ("/" not in span and not FILE_NAME.match(span)):
        return False
    parts = span.rstrip("/").split("/")
    return span.endswith("/") or bool(FILE_NAME.match(parts[-1])) or all(
        WORD.match(part) for part in parts)


def check_path(span: str) -> list:
    """Problems of a path: [] when a file or folder of that name exists."""
    if "/" in span.rstrip("/"):
        found = any((ROOT / base / span).exists() for base in PATH_ROOTS)
    else:
        name = span.rstrip("/")
        found = (ROOT / name).exists() or any(
            any(True for _ in (ROOT / folder).rglob(name)) for folder in FILE_FOLDERS)
    return [] if found else [f"no file or folder {span}"]


def _installed(name: str) -> bool:
    """Whether a dotted name is an attribute of an installed module (not the project's).
    Blender's modules are taken on trust: they are not imported outside Blender."""
    parts = name.split(".")
    if parts[0] in BLENDER_MODULES:
        return True
    if parts[0] == PACKAGE or importlib.util.find_spec(parts[0]) is None:
        return False
    for cut in range(len(parts), 0, -1):
        try:
            found = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for part in parts[cut:]:
            if not hasattr(found, part):
                return False
            found = getattr(found, part)
        return True
    return False


def check_name(name: str, definitions: Definitions) -> list:
    """Problems of a name or dotted name: [] when it is defined (module docstring)."""
    root, _, rest = name.partition(".")
    if not rest:
        known = (_not_checked(name) or name in dir(builtins) or name in definitions.bare
                 or name in definitions.strings)
    else:
        read_off_a_parameter = (root in definitions.variables and root not in definitions.scopes
                                and any(d.endswith("." + rest) for d in definitions.dotted))
        known = name in definitions.dotted or read_off_a_parameter or _installed(name)
    return [] if known else [f"no definition of {name}"]


def check_string(value: str, definitions: Definitions) -> list:
    return [] if value in definitions.strings else [f"no string constant {value!r} in the code"]


def _dotted(node: ast.AST) -> str | None:
    """"a.b.c" of a Name or Attribute chain, or None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return ".".join([node.id, *reversed(parts)]) if isinstance(node, ast.Name) else None


def _parameters(callee: str | None, definitions: Definitions) -> set | None:
    """The keywords a callable takes, or None when it is not known."""
    if callee in definitions.parameters:
        return definitions.parameters[callee]
    if callee and "." in callee and _installed(callee):
        module, _, name = callee.rpartition(".")
        try:
            return set(inspect.signature(getattr(importlib.import_module(module), name))
                       .parameters)
        except (ImportError, AttributeError, TypeError, ValueError):
            return None
    return None


def check_reference(tree: ast.AST, definitions: Definitions) -> list:
    """Problems of a parsed Python reference (see the module docstring)."""
    problems = []
    inner = {id(node.value) for node in ast.walk(tree) if isinstance(node, ast.Attribute)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            callee = _dotted(node.func)
            accepted = _parameters(callee, definitions)
            for keyword in node.keywords:
                if accepted is not None and keyword.arg not in (*accepted, None) \
                        and not _not_checked(keyword.arg):
                    problems.append(f"{callee} takes no keyword {keyword.arg}")
                value = keyword.value
                if isinstance(value, ast.Constant) and isinstance(value.value, str):
                    problems += check_string(value.value, definitions)
        name = _dotted(node) if isinstance(node, (ast.Name, ast.Attribute)) else None
        if name and id(node) not in inner:
            problems += check_name(name, definitions)
    return problems


def check_span(span: str, definitions: Definitions) -> list:
    """The problems of one cited span: [] when what it names exists or it is not checked."""
    if not span.strip() or not span.isascii():
        return []
    if " " in span:
        problems = check_command(span.split(), definitions)
        if problems is not None:
            return problems
    if any(c in span for c in "<>{}*?") or span.startswith("-"):
        return []  # a pattern of names, or an option on its own
    if _is_path(span):
        return check_path(span)
    match = KEYWORD_VALUE.match(span)
    if match:
        name, value = match.groups()
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            return []  # a sentence, not code
        return check_name(name, definitions) + (
            check_string(value, definitions) if isinstance(value, str) else [])
    try:
        tree = ast.parse(span, mode="eval")
    except SyntaxError:
        return []
    if not all(isinstance(node, REFERENCE_NODES) for node in ast.walk(tree)):
        return []  # a formula
    return check_reference(tree, definitions)


def document_problems(text: str, definitions: Definitions) -> list:
    """["`span`: problem", ...] for a document's text, each span once."""
    return [f"`{span}`: {problem}" for span in dict.fromkeys(cited_spans(text))
            for problem in check_span(span, definitions)]


@pytest.fixture(scope="module")
def definitions() -> Definitions:
    return read_definitions()


@pytest.mark.parametrize("document", DOCUMENTS)
def test_every_cited_name_exists(document: str, definitions: Definitions) -> None:
    problems = document_problems((ROOT / document).read_text(encoding="utf-8"), definitions)
    assert not problems, (f"{document} cites {len(problems)} name(s) the project does not "
                          "have; rename them there too:\n  " + "\n  ".join(problems))


def test_the_check_reports_each_missing_name(definitions: Definitions) -> None:
    # one missing thing of each kind, each reported once and by name
    text = """
    `_level_start` `MapOptions.no_such_field` `chain._NO_WINDOW` `core/map/absent.py`
    `absent_module.py` `solve_map(no_keyword=1)` `transport="no-such-transport"`
    `python benchmarks/bench_solver.py --no-such-option` `python benchmarks/absent.py`
    `scripts/absent.sh 64` `python -m keyframe_implicit bake --no-such-option`
    `numpy.no_such_function` `no_such_parameter=3` `numpy.linalg.norm(no_keyword=0)`
    `MapOptions.weight`
    """
    problems = document_problems(text, definitions)
    for missing in ("_level_start", "MapOptions.no_such_field", "chain._NO_WINDOW",
                    "core/map/absent.py", "absent_module.py", "solve_map takes no keyword",
                    "'no-such-transport'", "bench_solver.py has no option --no-such-option",
                    "benchmarks/absent.py", "scripts/absent.sh",
                    "keyframe_implicit has no option --no-such-option",
                    "numpy.no_such_function", "no_such_parameter",
                    "numpy.linalg.norm takes no keyword", "MapOptions.weight"):
        assert sum(missing in p for p in problems) == 1, (missing, problems)
    assert len(problems) == 15, problems


def test_the_check_accepts_what_exists_and_skips_mathematics(definitions: Definitions) -> None:
    # existing names of each kind, and spans that are mathematics, values or patterns
    text = """
    `solve_map` `MapOptions.margin_cells` `system.HESSIAN_DTYPE` `core/map/solver.py`
    `map/rbf.py` `rbf.py` `blender/ops.py` `results/motion_grid.md` `core/bake/`
    `tear=True` `transport="two-sided"` `python benchmarks/bench_solver.py --region`
    `scipy.interpolate.RBFInterpolator(..., degree=1)` `bpy.types.Operator` `Φ < 0` `h`
    `A_ij` `y(x)` `x = 3` `h/2` `2^15` `"one-sided"` `min(2t, 1)` `preview_<scene>.png`
    `my_weight=...` `batch.weight`
    `bend_case` `bench_scale.py --cases merge` `python -m keyframe_implicit bake`
    ```
    not_a_name_in_a_fence
    ```
    """
    assert document_problems(text, definitions) == []
