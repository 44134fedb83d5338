"""fillgs: observation counts, motion-aware deficiency, selection and renders of 4D Gaussian
models, as NumPy arrays, over the same library the command line runs.

Everything is the extension module ``fillgs._fillgs`` (src/python/module.cpp); this file only
re-exports it and gives each function the signature its pybind11 declaration prints, so that
``inspect.signature`` and editors read the keywords and defaults. Stubs with the array types:
``__init__.pyi`` beside this file.
"""
import ast as _ast
import functools as _functools
import inspect as _inspect

from . import _fillgs
from ._fillgs import *  # noqa: F401,F403  (every public name)
from ._fillgs import Error  # noqa: F401

__version__ = _fillgs.__version__


class _Default:
    """A default pybind11 prints that is no Python literal (shown as printed)."""

    def __init__(self, text):
        self.text = text

    def __repr__(self):
        return self.text


def _split_top(text):
    """Splits `text` at the commas outside brackets and quotes."""
    parts, depth, quote, start = [], 0, None, 0
    for i, c in enumerate(text):
        if quote:
            quote = None if c == quote else quote
        elif c in "'\"":
            quote = c
        elif c in "([{":
            depth += 1
        elif c in ")]}":
            depth -= 1
        elif c == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    if text[start:].strip():
        parts.append(text[start:])
    return parts


def _signature(fn, name=None, skip_self=False):
    """The signature in the first line of a pybind11 docstring, "name(a: T, b: T = d) -> R"."""
    first = (fn.__doc__ or "").split("\n", 1)[0]
    name = name or fn.__name__
    if not first.startswith(name + "(") or ") -> " not in first:
        return None
    inner = first[len(name) + 1 : first.rindex(") -> ")]
    params = []
    for part in _split_top(inner)[1 if skip_self else 0 :]:
        if part.strip().startswith("**"):  # a row's own parameters (a format's, a refiner's) as keywords
            params.append(_inspect.Parameter(part.strip()[2:], _inspect.Parameter.VAR_KEYWORD))
            continue
        head, _, default = part.partition("=")
        pname = head.split(":", 1)[0].strip()
        if pname in ("*", "/") or not pname.isidentifier():
            return None
        if default:
            text = default.strip()
            try:
                value = _ast.literal_eval(text)
            except (ValueError, SyntaxError):
                value = _Default(text)
            params.append(_inspect.Parameter(pname, _inspect.Parameter.POSITIONAL_OR_KEYWORD, default=value))
        else:
            params.append(_inspect.Parameter(pname, _inspect.Parameter.POSITIONAL_OR_KEYWORD))
    return _inspect.Signature(params)


def _with_signature(fn):
    sig = _signature(fn)
    if sig is None:
        return fn

    @_functools.wraps(fn)
    def call(*args, **kwargs):
        return fn(*args, **kwargs)

    call.__signature__ = sig
    return call


for _name in dir(_fillgs):
    _obj = getattr(_fillgs, _name)
    if not _name.startswith("_") and type(_obj).__name__ == "builtin_function_or_method":
        globals()[_name] = _with_signature(_obj)
    elif isinstance(_obj, type) and not issubclass(_obj, BaseException):
        _sig = _signature(_obj.__init__, "__init__", skip_self=True)  # a class made from arrays (Cameras)
        if _sig is not None:
            _obj.__signature__ = _sig
del _name, _obj
