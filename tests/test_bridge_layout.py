"""The bridge package's layout (bridge/__init__.py): one module per concept, each name defined in
one module and imported from there, no module importing another that imports it, nothing private
read across modules. Read from the source, so no bpy is needed."""

import ast
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "bridge"
MODULES = sorted(path.stem for path in PACKAGE.glob("*.py") if path.stem != "__init__")
CALLERS = sorted([*ROOT.glob("operators/*.py"), *ROOT.glob("ui/*.py"), ROOT / "__init__.py", ROOT / "properties.py"])


def tree(path):
    return ast.parse(path.read_text(encoding="utf-8"))


def defined(module):
    """The top-level names ``bridge/<module>.py`` defines (not imports)."""
    names = set()
    for node in tree(PACKAGE / f"{module}.py").body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names |= {target.id for target in node.targets if isinstance(target, ast.Name)}
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return names


def sibling_imports(module):
    """``(module, names)`` of each import of another module of the package in ``bridge/<module>.py``
    (at the top or inside a function)."""
    out = []
    for node in ast.walk(tree(PACKAGE / f"{module}.py")):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module is None:
                out += [(alias.name, []) for alias in node.names]
            else:
                out.append((node.module, [alias.name for alias in node.names]))
    return out


def test_the_package_init_only_loads_and_lists_its_modules():
    init = tree(PACKAGE / "__init__.py")
    doc = ast.get_docstring(init)
    statements = init.body[1:]
    assert all(isinstance(node, ast.ImportFrom) and node.level == 1 and node.module is None
               for node in statements), "bridge/__init__.py defines or imports something besides its modules"
    loaded = {alias.name for node in statements for alias in node.names}
    assert loaded == set(MODULES)
    listed = set(re.findall(r"^- :mod:`(\w+)`: \S", doc, re.MULTILINE))
    assert listed == set(MODULES), "every module has its line in the package's docstring"


def test_every_name_is_defined_in_one_module():
    seen = {}
    for module in MODULES:
        for name in defined(module):
            assert name not in seen, f"'{name}' is defined in both {seen[name]} and {module}"
            seen[name] = module


@pytest.mark.parametrize("module", MODULES)
def test_a_module_imports_only_public_names_its_siblings_define(module):
    for other, names in sibling_imports(module):
        assert other in MODULES, f"{module} imports bridge.{other}, which is no module of the package"
        for name in names:
            assert not name.startswith("_"), f"{module} reads the private '{name}' of {other}"
            assert name in defined(other), f"{module} imports '{name}' from {other}, which does not define it"


def test_no_module_imports_one_that_imports_it():
    imports = {module: {other for other, _ in sibling_imports(module)} for module in MODULES}
    done, path = set(), []

    def visit(module):
        assert module not in path, f"import cycle: {' -> '.join(path + [module])}"
        if module in done:
            return
        path.append(module)
        for other in sorted(imports[module]):
            visit(other)
        path.pop()
        done.add(module)

    for module in MODULES:
        visit(module)


@pytest.mark.parametrize("caller", CALLERS, ids=[str(path.relative_to(ROOT)) for path in CALLERS])
def test_the_extension_imports_each_name_from_the_module_that_defines_it(caller):
    """``from ..bridge import frame_reading`` (a module) or ``from ..bridge.frame_reading import X``
    (a name it defines): one import path per name, and a test patching ``frame_reading.X`` patches
    what the caller reads."""
    for node in ast.walk(tree(caller)):
        if not (isinstance(node, ast.ImportFrom) and node.level):
            continue
        parts = (node.module or "").split(".")
        if parts == ["bridge"]:
            assert {alias.name for alias in node.names} <= set(MODULES), f"{caller.name}:{node.lineno}"
        elif parts[0] == "bridge":
            assert len(parts) == 2 and parts[1] in MODULES, f"{caller.name}:{node.lineno}"
            assert {alias.name for alias in node.names} <= defined(parts[1]), f"{caller.name}:{node.lineno}"
        elif node.module is None:
            assert "bridge" not in {alias.name for alias in node.names}, \
                f"{caller.name}:{node.lineno} imports the package: import its modules"


@pytest.mark.parametrize("caller", CALLERS, ids=[str(path.relative_to(ROOT)) for path in CALLERS])
def test_the_extension_binds_no_second_name_for_a_bridge_name(caller):
    """No module of the extension keeps a bridge name under a name of its own (``X = modifier_kinds.X``):
    it would be a second import path, and a test patching one would not patch the other."""
    modules = {alias.asname or alias.name for node in ast.walk(tree(caller))
               if isinstance(node, ast.ImportFrom) and node.level and (node.module or "") == "bridge"
               for alias in node.names}
    for node in tree(caller).body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and isinstance(node.value, ast.Attribute):
            value = node.value.value
            assert not (isinstance(value, ast.Name) and value.id in modules), \
                f"{caller.name}:{node.lineno} names {value.id}.{node.value.attr} again: use it from {value.id}"
