"""Every public function, class and block factory has a numpydoc docstring with an example."""

import importlib
import inspect
import pkgutil

import controlkit


def public_objects():
    for info in pkgutil.walk_packages(controlkit.__path__, "controlkit."):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if name.startswith("_") or not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            if getattr(obj, "__module__", None) != module.__name__:
                continue  # imported from elsewhere
            yield f"{module.__name__}.{name}", obj


def test_public_names_are_documented_with_an_example():
    missing = [name for name, obj in public_objects()
               if not obj.__doc__ or "Examples\n" not in inspect.cleandoc(obj.__doc__)]
    assert missing == [], f"public names without a numpydoc docstring and example: {missing}"


def test_docstrings_describe_parameters_of_block_factories():
    from controlkit.blocks import cmg, mec, spacecraft

    for module in (spacecraft, mec, cmg):
        for name, obj in vars(module).items():
            if inspect.isfunction(obj) and obj.__module__ == module.__name__ and \
                    "Returns\n" in inspect.cleandoc(obj.__doc__ or "") and \
                    "NonlinearIOSystem" in inspect.cleandoc(obj.__doc__):
                doc = inspect.cleandoc(obj.__doc__)
                assert "Inputs" in doc or "inputs" in doc, name
                assert "eq." in doc or "section" in doc, f"{name} cites no equation"
