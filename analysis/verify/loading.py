"""Load a user's verification problem from their own code: ``package.module:OBJECT`` or ``path/to/file.py:OBJECT``.

The object is a :class:`~analysis.verify.verification.VerificationProblem`, or a
function taking keyword options and returning one (``OBJECT`` then receives
the options the caller passes, e.g. ``variant="paper"``).  A module that does
not import is reported with the user's own traceback (it is their code); a
missing object names the module's public names; an object of the wrong type
says what was found.

Examples
--------
>>> split_spec("examples/thermostat.py:problem")
('examples/thermostat.py', 'problem')
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
import traceback
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from hybrid.errors import ParameterError

from analysis.verify.verification import VerificationProblem

__all__ = ["ProblemLoadError", "split_spec", "load_problem", "load_problems", "source_digests"]


class ProblemLoadError(ParameterError):
    """A problem specification that does not give a verification problem.

    ``user_traceback`` is the traceback of the user's own code when importing
    or calling it failed (empty otherwise).
    """

    def __init__(self, parameter: str, value: object, expected: str, fix: str, user_traceback: str = "") -> None:
        self.user_traceback = user_traceback
        super().__init__(parameter, value, expected, fix)

    def __reduce__(self):
        return (type(self), (self.parameter, self.value, self.expected, self.fix, self.user_traceback))


def split_spec(spec: str) -> tuple[str, str]:
    """``(module or file, object)`` of ``"MODULE:OBJECT"``; the object defaults to ``problem``.

    A Windows drive (``C:\\x.py:problem``) is not taken for the separator.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ProblemLoadError("problem", spec, "MODULE:OBJECT or path/to/file.py:OBJECT",
                               "write e.g. visnav verify examples/thermostat.py:problem")
    head, sep, tail = spec.rpartition(":")
    if not sep or not head or "/" in tail or "\\" in tail or (len(head) == 1 and head.isalpha()):
        return spec, "problem"
    return head, tail


def _user_traceback(error: BaseException, skip_own: bool = True) -> str:
    frames = traceback.extract_tb(error.__traceback__)
    root = Path(__file__).resolve().parents[2]
    own = tuple(str(root / package) + os.sep for package in ("analysis", "hybrid", "visnav"))
    kept = [f for f in frames if not (skip_own and f.filename.startswith(own))
            and "importlib" not in f.filename and "<frozen" not in f.filename] or frames
    lines = ["Traceback (most recent call last):\n", *traceback.format_list(kept),
             *traceback.format_exception_only(type(error), error)]
    return "".join(lines)


def _module_from_file(path: Path) -> ModuleType:
    name = "visnav_user_" + hashlib.sha256(str(path).encode()).hexdigest()[:12]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ProblemLoadError("problem file", str(path), "a Python source file", "give a .py file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    folder = str(path.parent)
    added = folder not in sys.path
    if added:
        sys.path.insert(0, folder)  # the user's sibling modules import as in their own scripts
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    finally:
        if added:
            sys.path.remove(folder)
    return module


def _import(where: str) -> ModuleType:
    is_file = where.endswith(".py") or os.sep in where or "/" in where
    try:
        if is_file:
            path = Path(where).expanduser().resolve()
            if not path.is_file():
                raise ProblemLoadError("problem file", where, "an existing .py file",
                                       "check the path (relative to the current folder)")
            return _module_from_file(path)
        return importlib.import_module(where)
    except (ProblemLoadError, ParameterError):
        raise  # the toolkit's own validation of what the module builds: its message says what to fix
    except ModuleNotFoundError as error:
        if not is_file and error.name and (error.name == where or where.startswith(error.name + ".")):
            raise ProblemLoadError("problem module", where, "an importable module",
                                   "install it, or give its file: path/to/file.py:OBJECT") from None
        raise ProblemLoadError("problem module", where, "a module that imports", "fix the error in your code",
                               _user_traceback(error)) from None
    except BaseException as error:  # the user's code failed while importing: show them their traceback
        if isinstance(error, KeyboardInterrupt):
            raise
        raise ProblemLoadError("problem module", where, "a module that imports", "fix the error in your code",
                               _user_traceback(error)) from None


def load_problem(spec: str, options: Mapping[str, Any] | None = None) -> VerificationProblem:
    """The verification problem ``spec`` names (see the module docstring).

    Parameters
    ----------
    spec : str
        ``"package.module:OBJECT"`` or ``"path/to/file.py:OBJECT"`` (``OBJECT`` defaults to ``problem``), or a
        SpaceEx model ``"FILE.xml"`` / ``"FILE.xml:COMPONENT"`` (:func:`analysis.spaceex.spaceex_problem`).
    options : Mapping or None
        Keyword arguments for an ``OBJECT`` that is a function; refused for a problem object.  For a SpaceEx
        model: ``{"config": "FILE.cfg"}``.

    Raises
    ------
    ProblemLoadError
        The module does not import (with the user's traceback), has no such
        object, the object is not a problem (nor a function returning one), or
        calling it failed.
    """
    if _is_spaceex(spec):
        return _spaceex(spec, options)
    where, name = split_spec(spec)
    module = _import(where)
    if not hasattr(module, name):
        public = sorted(n for n in vars(module) if not n.startswith("_"))
        raise ProblemLoadError("problem object", f"{where}:{name}", f"a name defined in {where}",
                               f"choose one of {public[:20]}")
    obj = getattr(module, name)
    if callable(obj) and not isinstance(obj, VerificationProblem):
        try:
            obj = obj(**dict(options or {}))
        except ProblemLoadError:
            raise
        except ParameterError:
            raise
        except BaseException as error:  # sys.exit(), GeneratorExit too: the user's code never sets our exit code
            if isinstance(error, KeyboardInterrupt):
                raise
            raise ProblemLoadError("problem object", f"{where}:{name}", "a function returning a VerificationProblem",
                                   "fix the error in your code", _user_traceback(error)) from None
    elif options:
        raise ProblemLoadError("problem options", dict(options), f"no options ({where}:{name} is not a function)",
                               "drop the options, or make OBJECT a function taking them")
    if not isinstance(obj, VerificationProblem):
        raise ProblemLoadError("problem object", f"{where}:{name}",
                               f"an analysis.verify.verification.VerificationProblem (found {type(obj).__name__})",
                               "build it with analysis.verify.problems.hybrid_problem(...) or sampled_problem(...)")
    if not obj.source:
        object.__setattr__(obj, "source", spec)
    return obj


def load_problems(spec: str) -> dict[str, VerificationProblem]:
    """The problems of a collection: ``"path/to/file.py:OBJECT"`` (``OBJECT`` defaults to ``problems``) names a
    mapping, or a function of no argument returning one, of keys (``"AT1"``, ``"CC1"``, ...) to problems.

    Raises
    ------
    ProblemLoadError
        As :func:`load_problem`; also for an object that is not such a mapping.
    """
    where, name = split_spec(spec if ":" in spec.replace("\\", "/").rsplit("/", 1)[-1] else f"{spec}:problems")
    module = _import(where)
    obj = getattr(module, name, None)
    if obj is None:
        public = sorted(n for n in vars(module) if not n.startswith("_"))
        raise ProblemLoadError("problems object", f"{where}:{name}", f"a name defined in {where}",
                               f"choose one of {public[:20]}")
    if callable(obj):
        try:
            obj = obj()
        except BaseException as error:
            if isinstance(error, KeyboardInterrupt):
                raise
            raise ProblemLoadError("problems object", f"{where}:{name}", "a function returning a mapping of problems",
                                   "fix the error in your code", _user_traceback(error)) from None
    if not isinstance(obj, Mapping) or not all(isinstance(k, str) and isinstance(v, VerificationProblem)
                                               for k, v in obj.items()):
        raise ProblemLoadError("problems object", f"{where}:{name}",
                               f"a mapping of names to VerificationProblem (found {type(obj).__name__})",
                               "return e.g. {'AT1': hybrid_problem(...)} from problems()")
    return dict(obj)


def _is_spaceex(spec: str) -> bool:
    from analysis.spaceex import is_spaceex_spec

    return is_spaceex_spec(spec)


def _spaceex(spec: str, options: Mapping[str, Any] | None) -> VerificationProblem:
    """A SpaceEx model ``FILE.xml[:COMPONENT]`` with the configuration ``options["config"]`` (``--config``)."""
    from analysis.spaceex import spaceex_problem, split_spaceex_spec

    opts = dict(options or {})
    config = opts.pop("config", None)
    if opts:
        raise ProblemLoadError("problem options", opts, "only config (the SpaceEx .cfg) for a SpaceEx model",
                               "drop the other options")
    if not config:
        raise ProblemLoadError("--config", None, f"the SpaceEx configuration FILE.cfg of {spec}",
                               f"add --config FILE.cfg (initially, forbidden, time-horizon)")
    xml, component = split_spaceex_spec(spec)
    problem = spaceex_problem(xml, config, component)
    object.__setattr__(problem, "source", spec)
    return problem


TOOLKIT_PACKAGES = ("hybrid", "analysis", "visnav")
"""The toolkit's packages: their sources simulate and judge every model, so they are part of its identity."""


def _tree_digest(folder: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(folder.rglob("*")):
        if path.suffix in (".py", ".toml") and "__pycache__" not in path.parts:
            digest.update(str(path.relative_to(folder)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def _file_digest(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    except OSError:
        return "unreadable"


def source_digests(spec: str, base: str | os.PathLike[str] | None = None,
                   data_files: Sequence[str | os.PathLike[str]] = ()) -> dict[str, str]:
    """What the results of problem ``spec`` depend on: SHA-256 (16 hex digits) of its code.

    The toolkit's packages (one digest each, over every ``.py`` and ``.toml`` file), and for a user's
    problem its module's file with every module loaded from the same folder (``FILE.py:OBJ``) or the
    same top-level package (``pkg.mod:OBJ``), keyed by path (a relative ``FILE.py`` is read from ``base``, the
    folder the command started in, when given).  Deterministic for a given tree: it does
    not depend on what was imported before.  A journal records these and refuses to resume when one
    changed (``visnav verify``).  Installed third-party packages are left out (the pinned set).
    """
    root = Path(__file__).resolve().parents[2]
    out = {f"toolkit:{name}": _tree_digest(root / name) for name in TOOLKIT_PACKAGES if (root / name).is_dir()}
    for data in data_files:  # a model given as data (a SpaceEx .cfg): its bytes are the model too
        path = Path(data).expanduser()
        path = (Path(base) / path if base is not None and not path.is_absolute() else path).resolve()
        out[str(path)] = _file_digest(path)
    if spec == "paper":
        return out
    where, _ = split_spec(spec)
    if where.endswith(".xml") or ".xml:" in spec:  # a SpaceEx model: the XML file is the model
        where = spec.split(".xml", 1)[0] + ".xml"
    is_file = where.endswith((".py", ".xml")) or os.sep in where or "/" in where
    if is_file:
        path = Path(where).expanduser()
        path = (Path(base) / path if base is not None and not path.is_absolute() else path).resolve()
        out[str(path)] = _file_digest(path)
        folder = path.parent
        for module in list(sys.modules.values()):
            file = getattr(module, "__file__", None)
            if isinstance(file, str) and file.endswith(".py") and Path(file).resolve().parent == folder:
                out[str(Path(file).resolve())] = _file_digest(Path(file).resolve())
        return dict(sorted(out.items()))
    top = where.split(".")[0]
    if top in TOOLKIT_PACKAGES:
        return out
    for name, module in list(sys.modules.items()):
        file = getattr(module, "__file__", None)
        if (name == top or name.startswith(top + ".")) and isinstance(file, str) and file.endswith(".py"):
            out[str(Path(file).resolve())] = _file_digest(Path(file).resolve())
    return dict(sorted(out.items()))
