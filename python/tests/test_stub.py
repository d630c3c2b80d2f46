"""The one stub file, ``adwi/__init__.pyi``, against the jobs' own options: every keyword
option a function takes is one of its job's (tablec's flags of the same names), with the
same default, and none is missing."""

import ast
from pathlib import Path

import adwi

STUB = Path(__file__).resolve().parents[1] / "adwi" / "__init__.pyi"

#: Keyword arguments the functions take apart from the job's options, and options the
#: job accepts for compatibility without documenting them.
APART = {"evaluate": {"validation"}}
HIDDEN = {"build": {"hybrid"}}


def stub_keywords(function: str):
    tree = ast.parse(STUB.read_text())
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and node.name == function:
            return {
                arg.arg: ast.literal_eval(default) if default is not None else None
                for arg, default in zip(node.args.kwonlyargs, node.args.kw_defaults)
            }
    raise AssertionError(f"{function} is not in the stub")


def test_the_stub_lists_every_option_of_each_job_with_its_default():
    for function in ("build", "evaluate", "calibrate", "plan", "iso9283"):
        options = {name: default for name, _, default in adwi._adwi.options(function)}
        stub = stub_keywords(function)
        names = set(stub) - APART.get(function, set()) - HIDDEN.get(function, set())
        assert names == set(options), function
        for name, default in options.items():
            if default is None:
                continue
            given = stub[name]
            if isinstance(given, bool):
                assert str(given).lower() == default, (function, name)
            elif isinstance(given, tuple):
                assert ",".join(f"{v:g}" for v in given) == default, (function, name)
            elif isinstance(given, (int, float)):
                assert given == float(default), (function, name, given, default)
            else:
                assert given == default, (function, name, given, default)


def test_every_option_is_documented_in_the_docstring():
    for function in (adwi.build, adwi.evaluate, adwi.calibrate, adwi.plan, adwi.iso9283):
        for name, _, _ in adwi._adwi.options(function.__name__):
            assert f"``{name}``" in function.__doc__, (function.__name__, name)
