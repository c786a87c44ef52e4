"""Localization methods by name: :data:`METHODS` maps a name to a :class:`Method`.

A :class:`Method` bundles the family's ``run(measurements, prior, rng, options) -> Result``, the
options dataclass it takes and the option values that make this named variant (``pfbp_reg`` is
``pfbp`` with ``regularize = True``). Experiments and recipes only ever look methods up here,
so they never branch on names, and a user's own method runs through ``phyloc evaluate`` once it
is registered (:func:`register_method`; from the command line, ``--plugin MODULE`` imports the
module that registers it).

Examples
--------
>>> from phyloc.localization import METHODS
>>> METHODS["dipnet"].family
'direct'
>>> "pfbp_reg" in METHODS and "poa_nbp" in METHODS
True

References
----------
L. Buitinck et al., "API design for machine learning software: experiences from the
scikit-learn project," ECML PKDD Workshop, 2013 (one entry point per estimator, a common
contract checked by one test).
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import os
import sys
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field

from phyloc.errors import PhylocError, ValidationError

#: Environment variable listing plugin modules (``os.pathsep``-separated module names or
#: ``.py`` paths) that :func:`load_plugins` imports; ``phyloc evaluate --plugin`` sets it so
#: that Dask worker processes started afterwards register the same methods.
PLUGINS_ENV = "PHYLOC_PLUGINS"
#: Entry-point group of installed packages that register methods when imported.
ENTRY_POINT_GROUP = "phyloc.methods"

#: The families a method can belong to; each has its own measurement and prior types.
FAMILIES = ("direct", "tracking", "static")


@dataclass(frozen=True)
class Method:
    """One named localization method.

    Attributes
    ----------
    name : str
        The registry key (what recipes write in ``experiment.methods``).
    family : str
        One of :data:`FAMILIES`: which measurements and prior ``run`` takes.
    run : callable
        ``run(measurements, prior, rng, options) -> Result``.
    options : type
        The options dataclass; it has ``from_dict(table, section)``.
    defaults : dict
        Option values of this named variant, applied before a recipe's own keys.
    label : str
        Display name in tables and figures (default: the name).
    inputs : str
        What the method consumes, in the family's words (direct family: ``"tables"`` for
        correlation tables, ``"ranges:<estimator>"`` for ranges of a range estimator).
    description : str
        One line for listings.
    """

    name: str
    family: str
    run: Callable
    options: type
    defaults: dict = field(default_factory=dict)
    label: str = ""
    inputs: str = ""
    description: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValidationError("method name", self.name, "a Python identifier, e.g. 'my_bp'")
        if self.family not in FAMILIES:
            raise ValidationError(
                f"method {self.name!r}: family", self.family, "one of " + ", ".join(FAMILIES)
            )
        if not callable(self.run):
            raise ValidationError(f"method {self.name!r}: run", self.run, "a callable")
        if not dataclasses.is_dataclass(self.options):
            raise ValidationError(f"method {self.name!r}: options", self.options, "a dataclass")
        if not self.label:
            object.__setattr__(self, "label", self.name)

    def make_options(self, table: dict | None = None, section: str = "localization"):
        """The options of this method: its ``defaults`` updated by a recipe ``table``.

        Unknown keys raise :class:`~phyloc.errors.ValidationError` naming ``section.key``.
        """
        from phyloc._validate import check_types

        merged = {**self.defaults, **(table or {})}
        if dataclasses.is_dataclass(self.options):
            check_types(self.options, merged, section)
        from_dict = getattr(self.options, "from_dict", None)
        if from_dict is not None:
            return from_dict(merged, section)
        from phyloc._validate import check_keys

        check_keys(merged, [f.name for f in dataclasses.fields(self.options)], section)
        return self.options(**merged)


class Registry(Mapping):
    """A read-only mapping name → :class:`Method` with :meth:`register`."""

    def __init__(self):
        self._methods: dict[str, Method] = {}

    def __getitem__(self, name: str) -> Method:
        try:
            return self._methods[name]
        except (KeyError, TypeError):  # TypeError: a list or table given as a name
            raise ValidationError(
                "method", name, "a registered method: " + ", ".join(self._methods)
            ) from None

    def __contains__(self, name) -> bool:
        return isinstance(name, str) and name in self._methods

    def get(self, name, default=None):
        """The method registered as ``name``, or ``default``."""
        return self._methods.get(name, default) if isinstance(name, str) else default

    def __iter__(self) -> Iterator[str]:
        return iter(self._methods)

    def __len__(self) -> int:
        return len(self._methods)

    def __repr__(self) -> str:
        return f"Registry({', '.join(self._methods)})"

    def family(self, family: str) -> tuple[str, ...]:
        """Names of the registered methods of one family, in registration order."""
        return tuple(n for n, m in self._methods.items() if m.family == family)

    def register(self, method: Method, *, replace: bool = False) -> Method:
        """Add ``method``; an existing name is an error unless ``replace``."""
        if not isinstance(method, Method):
            raise ValidationError("method", method, "a phyloc.localization.Method")
        if method.name in self._methods and not replace:
            raise ValidationError(
                "method name", method.name, "already registered (pass replace=True to replace it)"
            )
        self._methods[method.name] = method
        return method


#: Every registered localization method, by name.
METHODS = Registry()


def register_method(
    name: str,
    *,
    family: str,
    run: Callable,
    options: type,
    defaults: dict | None = None,
    label: str = "",
    inputs: str = "",
    description: str = "",
    replace: bool = False,
) -> Method:
    """Register a localization method under ``name`` (see :class:`Method`) and return it.

    Examples
    --------
    A method of the direct family that keeps every agent at its prior mean (a baseline):

    >>> import numpy as np
    >>> from dataclasses import dataclass
    >>> from phyloc.localization import METHODS, Result, Timing, register_method
    >>> @dataclass(frozen=True)
    ... class StayOptions:
    ...     pass
    >>> def stay(measurements, prior, rng, options):
    ...     mean = prior.particles.mean(axis=1)[None]
    ...     return Result(mean, None, Timing(0.0, np.zeros(1), np.zeros(1)), label=prior.label)
    >>> _ = register_method("stay_doc", family="direct", run=stay, options=StayOptions,
    ...                     inputs="ranges:corr", replace=True)
    >>> METHODS["stay_doc"].family
    'direct'
    """
    if _importing and callable(run):  # registered by a plugin: its errors name it
        run = PluginRun(run, name, os.path.basename(_importing[-1]))
    return METHODS.register(
        Method(
            name=name,
            family=family,
            run=run,
            options=options,
            defaults=dict(defaults or {}),
            label=label,
            inputs=inputs,
            description=description,
        ),
        replace=replace,
    )


_loaded: set[str] = set()
_importing: list[str] = []  # the plugin being imported (its methods' runs are wrapped)


class PluginError(PhylocError):
    """A plugin failed: its file does not import, or one of its methods raised (the message
    names the method and the file; ``phyloc --debug`` shows the plugin's traceback)."""


@dataclass(frozen=True)
class PluginRun:
    """A plugin method's ``run``: calls it, and turns an exception it raises into a
    :class:`PluginError` naming the method and its plugin file (chained to the original, for
    ``--debug``). Picklable where ``fn`` is (worker processes import the plugin too)."""

    fn: Callable
    method: str
    source: str

    def __call__(self, *args, **kwargs):
        try:
            return self.fn(*args, **kwargs)
        except PhylocError:
            raise
        except Exception as exc:
            raise PluginError(
                f"error in plugin method {self.method!r} ({self.source}): "
                f"{type(exc).__name__}: {exc} (phyloc --debug ... shows its traceback)"
            ) from exc


def _import_plugin(spec: str) -> None:
    if spec.endswith(".py"):
        path = os.path.abspath(spec)
        if not os.path.isfile(path):
            raise ValidationError(
                "--plugin", spec, "an importable module name or an existing .py file"
            )
        name = "phyloc_plugin_" + os.path.splitext(os.path.basename(path))[0]
        module_spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(module_spec)
        sys.modules[name] = module
        _importing.append(path)
        try:
            module_spec.loader.exec_module(module)
        except SyntaxError as exc:
            sys.modules.pop(name, None)
            raise PluginError(f"plugin {path} line {exc.lineno}: SyntaxError: {exc.msg}") from exc
        except Exception as exc:
            sys.modules.pop(name, None)
            raise PluginError(
                f"plugin {path} failed to import: {type(exc).__name__}: {exc} "
                "(phyloc --debug ... shows its traceback)"
            ) from exc
        finally:
            _importing.pop()
    else:
        _importing.append(spec)
        try:
            importlib.import_module(spec)
        except ImportError as exc:
            if getattr(exc, "name", None) == spec:
                raise ValidationError(
                    "--plugin", spec, f"an importable module name or a .py file ({exc})"
                ) from None
            raise PluginError(
                f"plugin module {spec} failed to import: {type(exc).__name__}: {exc}"
            ) from exc
        except SyntaxError as exc:
            raise PluginError(
                f"plugin module {spec} ({exc.filename} line {exc.lineno}): SyntaxError: {exc.msg}"
            ) from exc
        except Exception as exc:
            raise PluginError(
                f"plugin module {spec} failed to import: {type(exc).__name__}: {exc} "
                "(phyloc --debug ... shows its traceback)"
            ) from exc
        finally:
            _importing.pop()


def load_plugins(specs=None) -> None:
    """Import the modules that register user methods (each once per process).

    Parameters
    ----------
    specs : sequence of str, optional
        Module names or paths of ``.py`` files. Default: those of the environment variable
        :data:`PLUGINS_ENV`, then every entry point of the group :data:`ENTRY_POINT_GROUP`.
    """
    if specs is None:
        specs = [s for s in os.environ.get(PLUGINS_ENV, "").split(os.pathsep) if s]
        from importlib.metadata import entry_points

        for ep in entry_points(group=ENTRY_POINT_GROUP):
            if ep.value not in _loaded:
                _loaded.add(ep.value)
                ep.load()
    for spec in specs:
        if spec not in _loaded:
            _import_plugin(spec)
            _loaded.add(spec)


def method_names() -> list[str]:
    """The names this process has registered (run on Dask workers to see what they know)."""
    return list(METHODS)


def plugin_methods() -> list[str]:
    """The methods registered by plugins in this process."""
    return [name for name in METHODS if isinstance(METHODS[name].run, PluginRun)]


def add_plugins(specs) -> None:
    """Import ``specs`` now and record them in :data:`PLUGINS_ENV` for worker processes."""
    specs = [str(s) for s in specs]
    paths = [os.path.abspath(s) if s.endswith(".py") else s for s in specs]
    load_plugins(paths)
    old = [s for s in os.environ.get(PLUGINS_ENV, "").split(os.pathsep) if s]
    os.environ[PLUGINS_ENV] = os.pathsep.join(dict.fromkeys([*old, *paths]))
