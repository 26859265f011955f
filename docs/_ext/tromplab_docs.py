"""Pages of the documentation generated from the code, so that they cannot drift from it.

- :func:`cli_reference` walks the argparse parser of ``tromplab.cli`` (every command and
  subcommand, every option with its help text);
- :func:`formula_catalogue` writes one section per formula of ``tromplab.ALL_FORMULAS``
  (expression, parameters with bounds, slope at the cut, a figure of the curve family,
  citation, simulator conventions of ``tromplab export``);
- :func:`density_catalogue` writes one section per density partition curve of
  ``tromplab.density.registry.DENSITY_CURVES`` (expression, parameters, indices of an example,
  a figure, citation), appended to the formula catalogue;
- :func:`api_reference` lists every name of ``tromplab.__all__`` and the public functions and
  classes of each module of the package for autosummary.

The functions return reStructuredText and import nothing from Sphinx, so the tests can run
them (``tests/test_docs_generators.py``); :func:`setup` makes this module a Sphinx extension
that writes the pages into ``docs/generated/`` when the configuration is read.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import pkgutil
import re
import textwrap
from pathlib import Path

GENERATED = "generated"


# --- helpers --------------------------------------------------------------------------
def _title(text: str, char: str) -> str:
    return f"{text}\n{char * len(text)}\n"


def _indent(text: str, spaces: int = 3) -> str:
    return textwrap.indent(text, " " * spaces)


def _literal(text: str) -> str:
    """Inline literal that survives backquotes and empty text."""
    text = str(text).replace("`", "'")
    return f"``{text}``" if text.strip() else "(none)"


#: An option as typed in a help text (``--size-unit``, ``-o``, ``--fine-yield=0.3``): shown as a
#: literal, so that the HTML shows it as typed (Sphinx's smart quotes turn a bare ``--`` into a dash).
#: A name followed by a parenthesis is a function in a formula (``1 - exp(-exp(t))``), not an option.
OPTION_IN_TEXT = re.compile(r"(?<![\w-])(--?[A-Za-z][\w-]*(?:=[\w.]+)?)(?![\w(-])")


def _rst_plain(text: str) -> str:
    text = text.replace("\\", "\\\\").replace("*", "\\*").replace("|", "\\|").replace("`", "'")
    return re.sub(r"(?<![\w\\])_", r"\\_", text)


def _rst_text(text: str) -> str:
    """Plain text (help strings, notes) safe inside reStructuredText paragraphs, options as literals."""
    parts = OPTION_IN_TEXT.split(" ".join(str(text).split()))
    return "".join(_literal(part) if i % 2 else _rst_plain(part) for i, part in enumerate(parts))


# --- the command line -----------------------------------------------------------------
def find_parser_factory(module=None):
    """The function of ``tromplab.cli`` that builds the parser (``build_parser`` or ``_parser``)."""
    if module is None:
        module = importlib.import_module("tromplab.cli")
    for name in ("build_parser", "_parser", "parser", "make_parser", "get_parser"):
        factory = getattr(module, name, None)
        if callable(factory):
            return factory
    raise LookupError(f"no parser factory (build_parser or _parser) in {module.__name__}")


def build_cli_parser() -> argparse.ArgumentParser:
    return find_parser_factory()()


def _subparser_actions(parser: argparse.ArgumentParser):
    return [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]


def iter_commands(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()):
    """``(path, parser, help)`` for every command and subcommand, depth first, in declared order."""
    for action in _subparser_actions(parser):
        helps = {choice.dest: choice.help for choice in action._choices_actions}
        seen = set()
        for name, sub in action.choices.items():
            if id(sub) in seen:  # aliases point to the same parser
                continue
            seen.add(id(sub))
            path = (*prefix, name)
            yield path, sub, helps.get(name) or ""
            yield from iter_commands(sub, path)


def _expand_help(action: argparse.Action, prog: str) -> str:
    text = action.help or ""
    if "%" not in text:
        return text
    values = {name: value for name, value in vars(action).items() if value is not argparse.SUPPRESS}
    for name, value in list(values.items()):
        if hasattr(value, "__name__"):
            values[name] = value.__name__
    if values.get("choices") is not None:
        values["choices"] = ", ".join(map(str, values["choices"]))
    try:
        return text % dict(values, prog=prog)
    except (KeyError, TypeError, ValueError):
        return text


def _action_signature(action: argparse.Action) -> str:
    if not action.option_strings:
        return action.metavar or action.dest
    if action.nargs == 0:
        return ", ".join(action.option_strings)
    metavar = action.metavar
    if metavar is None:
        metavar = "{" + ",".join(map(str, action.choices)) + "}" if action.choices else action.dest.upper()
    if isinstance(metavar, tuple):
        metavar = " ".join(metavar)
    return ", ".join(f"{flag} {metavar}" for flag in action.option_strings)


def _documented_actions(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)) or action.help == argparse.SUPPRESS:
            continue
        yield action


def _options_block(parser: argparse.ArgumentParser) -> str:
    lines = []
    for action in _documented_actions(parser):
        details = []
        if action.choices is not None and not isinstance(action.choices, dict):
            details.append("choices: " + ", ".join(_literal(choice) for choice in action.choices))
        if action.required and action.option_strings:
            details.append("required")
        help_text = _rst_text(_expand_help(action, parser.prog))
        if details:
            help_text = f"{help_text} ({'; '.join(details)})" if help_text else f"({'; '.join(details)})"
        lines.append(_literal(_action_signature(action)))
        lines.append(_indent(help_text or "(no help text)") + "\n")
    return "\n".join(lines)


def _subcommand_list(parser: argparse.ArgumentParser) -> str:
    lines = []
    for action in _subparser_actions(parser):
        for choice in action._choices_actions:
            lines.append(
                f"- :ref:`{parser.prog} {choice.dest} <{_cli_label(parser.prog, choice.dest)}>`: {_rst_text(choice.help or '')}"
            )
    return "\n".join(lines) + "\n" if lines else ""


def _cli_label(prog: str, name: str = "") -> str:
    return "cli-" + "-".join((prog + " " + name).split()[1:] or ["main"])


def _usage(parser: argparse.ArgumentParser) -> str:
    usage = parser.format_usage().strip()
    return usage[len("usage: ") :] if usage.startswith("usage: ") else usage


def _command_section(parser: argparse.ArgumentParser, help_text: str, char: str) -> str:
    parts = [f".. _{_cli_label(parser.prog)}:\n", _title(_literal(parser.prog), char)]
    summary = help_text or parser.description or ""
    if summary:
        parts.append(_rst_text(summary) + "\n")
    if parser.description and parser.description != summary:
        parts.append(_rst_text(parser.description) + "\n")
    parts.append(".. code-block:: text\n\n" + _indent(_usage(parser)) + "\n")
    subcommands = _subcommand_list(parser)
    if subcommands:
        parts.append("Subcommands:\n\n" + subcommands)
    options = _options_block(parser)
    if options:
        parts.append("Arguments and options:\n\n" + options)
    if parser.epilog:
        parts.append(_rst_text(parser.epilog) + "\n")
    return "\n".join(parts)


def cli_reference(parser: argparse.ArgumentParser | None = None) -> str:
    """The CLI reference page: the main parser, then each command and subcommand."""
    parser = parser or build_cli_parser()
    levels = "=-~^"
    parts = [
        ".. This page is generated from the argparse parser of tromplab.cli by docs/_ext/tromplab_docs.py.\n",
        _title("Command-line reference", "#"),
        "Every command and option of ``tromplab``, generated from the parser the command line "
        "itself uses (``tromplab COMMAND --help`` prints the same).\n",
        _command_section(parser, parser.description or "", levels[0]),
    ]
    for path, sub, help_text in iter_commands(parser):
        parts.append(_command_section(sub, help_text, levels[min(len(path), len(levels) - 1)]))
    return "\n".join(parts)


# --- the formula catalogue ------------------------------------------------------------
#: shapes drawn in a family figure: slopes at the cut, clipped to the attainable range
FAMILY_SLOPES = (-0.3, -0.5, -0.75, -1.0, -1.5, -2.5, -4.0)


def _math_block(formula) -> str:
    """The ``.. math::`` block of the formula's own docstring, or its plain expression."""
    doc = inspect.getdoc(formula.phi) or ""
    match = re.search(r"^\.\. math::\n((?:[ \t]+.*\n?|\n)+)", doc, flags=re.MULTILINE)
    if match:
        return ".. math::\n\n" + _indent(textwrap.dedent(match.group(1)).strip()) + "\n"
    return f"{_literal(formula.expression)}\n"


def family_shapes(formula) -> list[float]:
    """Shapes for the family figure: the bounds (when finite) and shapes of typical slopes."""
    import numpy as np

    low, high = formula.shape_bounds
    shapes = {formula.clip_shape(formula.shape_for_slope(slope)) for slope in FAMILY_SLOPES}
    shapes |= {value for value in (low, high) if np.isfinite(value) and value > 0}
    return sorted(shapes)


def _curve_context(formula) -> dict:
    return {**formula.defaults, **{extra.name: extra.start for extra in formula.extras if extra.start is not None}}


def draw_family(formula, path: Path) -> None:
    """Partition to fines against x = size/d_cut for shapes over the formula's range (no pyplot)."""
    import matplotlib
    import numpy as np
    from matplotlib.figure import Figure

    x = np.geomspace(0.05, 20.0, 600)
    context = _curve_context(formula)
    figure = Figure(figsize=(6.4, 3.6), dpi=100, layout="constrained")
    ax = figure.add_subplot()
    shapes = family_shapes(formula)
    cmap = matplotlib.colormaps["viridis"]
    for i, shape in enumerate(shapes):
        colour = cmap(i / max(len(shapes) - 1, 1))
        with np.errstate(all="ignore"):
            phi = formula.phi(x, shape, **context)
        ax.plot(x, phi, color=colour, label=f"{formula.shape_name} = {shape:.3g}")
    ax.axhline(0.5, color="0.6", linewidth=0.8, linestyle=":")
    ax.axvline(1.0, color="0.6", linewidth=0.8, linestyle=":")
    ax.set_xscale("log")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("relative size x = size / d_cut")
    ax.set_ylabel("partition to the fine product")
    extra = ", ".join(f"{name} = {value:g}" for name, value in context.items())
    ax.set_title(f"({formula.equation}) {formula.id}" + (f" ({extra})" if extra else ""), fontsize=10)
    ax.legend(fontsize=7, loc="lower left", frameon=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)


def _export_module():
    for name in ("tromplab.output.export", "tromplab.export"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        if hasattr(module, "export_fits") and hasattr(module, "FittedCurve"):
            return module
    return None


def export_conventions(formula) -> list[str]:
    """Conventions of ``tromplab export`` that express this formula (found by exporting one fit)."""
    module = _export_module()
    if module is None:
        return []
    shape = formula.clip_shape(formula.shape_for_slope(-1.0))
    extras = {extra.name: extra.start if extra.start is not None else 0.0 for extra in formula.extras}
    fit = module.FittedCurve("example", formula.id, 1.0, shape, extras)
    names = []
    conventions = [*getattr(module, "CONVENTIONS", {}), "csv-long"]
    for convention in conventions:
        try:
            result = module.export_fits([fit], convention, size_unit="um")
        except Exception:  # noqa: BLE001 - a convention that cannot take this fit does not map it
            continue
        if len(result.table) and not result.skipped:
            names.append(convention)
    return names


def _parameter_rows(formula) -> list[tuple[str, str, str, str]]:
    rows = [("d_cut", "min(size)/100 .. max(size)*100", "size", "cut size: the size with partition 1/2 to each product")]
    for parameter in (formula.shape_parameter, *formula.extras):
        unit = {"1": "-", "size": "size"}.get(parameter.unit, parameter.unit or "-")
        rows.append((parameter.name, f"[{parameter.lower:g}, {parameter.upper:g}]", unit, parameter.meaning))
    return rows


def _table(header: tuple[str, ...], rows) -> str:
    lines = [".. list-table::", "   :header-rows: 1", ""]
    for row in (header, *rows):
        cells = [_rst_text(cell) or "-" for cell in row]
        cells = ["\\-" if cell == "-" else cell for cell in cells]  # a bare "-" would start a bullet list
        lines.append("   * - " + cells[0])
        lines.extend(f"     - {cell}" for cell in cells[1:])
    return "\n".join(lines) + "\n"


SHUVALOV_2018 = (
    "Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a dependence for the Tromp "
    "separation curve approximation. *Vestnik IGEU* 6, 15-23. doi:10.17588/2072-2672.2018.6.015-023"
)

FAMILY_TITLES = {
    "paper": "The nine formulas of Shuvalov et al. (2018)",
    "extended": "Extended curves: bypass and fish-hook",
    "other": "Curves of other tools",
}


def formula_section(formula, figure: str | None) -> str:
    """One catalogue section: expression, parameters, slope, figure, citation, conventions."""
    parts = [f".. _formula-{formula.id}:\n", _title(f"({formula.equation}) {formula.title}", "-")]
    parts.append(
        f"Registry id {_literal(formula.id)}, family {_literal(formula.family)}, {formula.n_params} fitted parameters.\n"
    )
    parts.append(_math_block(formula))
    parts.append(f"Reader syntax: {_literal(formula.expression)} with ``x = size/d_cut``.\n")
    parts.append(_table(("parameter", "bounds", "unit", "meaning"), _parameter_rows(formula)))
    shape = formula.clip_shape(formula.shape_for_slope(-1.0))
    parts.append(
        f"Slope at the cut: {_literal(formula.slope_expression)} "
        f"({formula.shape_name} = {shape:.4g} gives {formula.slope_at_cut(shape):.4g}"
        f"{' with the extra parameters at zero' if formula.extras else ''}).\n"
    )
    if formula.notes:
        parts.append(f"Notes: {_rst_text(formula.notes)}\n")
    if formula.lower_bound_reason:
        parts.append(f"Lower shape bound: {_rst_text(formula.lower_bound_reason)}\n")
    if formula.nests:
        parts.append(f"Reduces to :ref:`formula-{formula.nests}` when its extra parameters vanish.\n")
    if figure:
        parts.append(
            f".. figure:: {figure}\n   :alt: family of {formula.id} curves\n\n"
            f"   Partition to the fine product of {formula.id} for shapes over its range (the bounds and the "
            "shapes of slopes -0.3 to -4 at the cut).\n"
        )
    parts.append(f"Citation: {_rst_text(formula.citation)}\n")
    conventions = export_conventions(formula)
    if conventions:
        mapped = ", ".join(_literal(name) for name in conventions)
        parts.append(f"``tromplab export --to``: {mapped} (see :doc:`../export`).\n")
    else:
        parts.append("``tromplab export``: no simulator convention expresses this curve.\n")
    return "\n".join(parts)


def formula_catalogue(formulas=None, *, figure_dir: Path | None = None, figure_prefix: str = "formulas") -> str:
    """The catalogue page over ``formulas`` (default ``tromplab.ALL_FORMULAS``); figures into ``figure_dir``."""
    import tromplab

    formulas = tuple(tromplab.ALL_FORMULAS if formulas is None else formulas)
    parts = [
        ".. This page is generated from tromplab.ALL_FORMULAS by docs/_ext/tromplab_docs.py.\n",
        _title("Formula catalogue", "#"),
        f"Every separation-curve formula of the registry ({len(formulas)} in all), generated from its "
        "declaration record: a formula added to the registry appears here with no other edit. "
        "Each curve is the partition number to the fine product, phi(x), of the relative size "
        "x = size/d_cut, with phi(1) = 1/2. Corrections of printed forms are in :doc:`../errata`; "
        "names other tools give these curves in :doc:`../curves`.\n",
        # the registry's docstrings cite [Shuvalov2018]_; Sphinx citations are global, defined here once
        ".. [Shuvalov2018] " + SHUVALOV_2018 + "\n",
    ]
    families = list(dict.fromkeys(formula.family for formula in formulas))
    for family in families:
        parts.append(_title(FAMILY_TITLES.get(family, f"Family {family}"), "="))
        for formula in (f for f in formulas if f.family == family):
            figure = None
            if figure_dir is not None:
                draw_family(formula, Path(figure_dir) / f"{formula.id}.png")
                figure = f"{figure_prefix}/{formula.id}.png"
            parts.append(formula_section(formula, figure))
    return "\n".join(parts)


# --- the density curves -----------------------------------------------------------------
#: The standard forms F of the density curves in LaTeX, by their binomial link.
DENSITY_FORMS_TEX = {
    "probit": r"\Phi(t) = \tfrac12 \operatorname{erfc}(-t/\sqrt2)",
    "logit": r"\frac{1}{1 + e^{-t}}",
    "cloglog": r"1 - \exp\left(-e^{t}\right)",
}
#: The curves drawn in a density figure: rho50 and, for the plain curves, Ep; for the curves
#: with limits Ep 0.04 and these (light, heavy) limits.
DENSITY_FIGURE_CUT = 1.5
DENSITY_FIGURE_EPS = (0.02, 0.04, 0.08)
DENSITY_FIGURE_LIMITS = ((0.0, 1.0), (0.03, 0.97), (0.1, 0.9))


def _density_math(curve) -> str:
    form = curve.form
    centre = "" if form.centre == 0.0 else f"{form.centre:.10g} + "
    cut, ep = (r"\rho_c", r"E_{p,c}") if curve.has_limits else (r"\rho_{50}", r"E_p")
    outer = r"l + (h - l)\,F(t)" if curve.has_limits else "F(t)"
    inner = DENSITY_FORMS_TEX.get(form.link)
    lines = [rf"P(\rho) = {outer}, \qquad t = {centre}{form.scale:.10g}\,\frac{{\rho - {cut}}}{{{ep}}}"]
    if inner:
        lines.append(rf"F(t) = {inner}")
    return ".. math::\n\n" + "\n\n".join(_indent(line) for line in lines) + "\n"


def _density_examples(curve) -> list[tuple[str, dict]]:
    """(label, parameters) of the curves drawn for ``curve``: cut 1.5 and several Ep or limits."""
    if not curve.has_limits:
        return [(f"Ep = {ep:g}", curve.from_indices(rho50=DENSITY_FIGURE_CUT, ep=ep)) for ep in DENSITY_FIGURE_EPS]
    return [
        (
            f"l = {light:g}, h = {heavy:g}",
            curve.from_indices(rho50=DENSITY_FIGURE_CUT, ep=0.04, light_limit=light, heavy_limit=heavy),
        )
        for light, heavy in DENSITY_FIGURE_LIMITS
    ]


def draw_density_family(curve, path: Path) -> None:
    """Partition to sinks (%) against relative density of ``curve`` for the examples (no pyplot)."""
    import numpy as np
    from matplotlib.figure import Figure

    rho = np.linspace(1.2, 1.8, 600)
    figure = Figure(figsize=(6.4, 3.4), dpi=100, layout="constrained")
    ax = figure.add_subplot()
    for i, (label, params) in enumerate(_density_examples(curve)):
        ax.plot(rho, 100.0 * curve.partition(rho, **params), color=f"C{i}", label=label)
    ax.axhline(50.0, color="0.6", linewidth=0.8, linestyle=":")
    ax.axvline(DENSITY_FIGURE_CUT, color="0.6", linewidth=0.8, linestyle=":")
    ax.set_xlabel("relative density (g/cm3)")
    ax.set_ylabel("partition to sinks (%)")
    ax.set_ylim(-2, 102)
    ax.set_title(f"{curve.id}: rho50 = {DENSITY_FIGURE_CUT:g}" + (", Ep = 0.04" if curve.has_limits else ""), fontsize=10)
    ax.legend(fontsize=7, loc="lower right", frameon=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)


def density_curve_section(curve, figure: str | None) -> str:
    """One section of the density catalogue: expression, parameters, indices, figure, citation."""
    parts = [f".. _density-{curve.id}:\n", _title(curve.title, "-")]
    parts.append(f"Registry id {_literal(curve.id)}, binomial link {_literal(curve.link)}, {curve.n_params} fitted parameters.\n")
    parts.append(_density_math(curve))
    parts.append(f"Plain text: {_literal(curve.expression)}.\n")
    rows = [(p.name, f"[{p.lower:g}, {p.upper:g}]", {"1": "-"}.get(p.unit, p.unit or "-"), p.meaning) for p in curve.parameters]
    parts.append(_table(("parameter", "bounds", "unit", "meaning"), rows))
    label, params = _density_examples(curve)[1]
    index = curve.indices(**params)
    parts.append(
        f"Indices of the example with rho50 = {DENSITY_FIGURE_CUT:g} and {label if curve.has_limits else 'Ep = 0.04'}"
        f"{' (Ep = 0.04)' if curve.has_limits else ''}: rho25 = {index.rho25:.4f}, rho75 = {index.rho75:.4f}, "
        f"Ep = (rho75 - rho25)/2 = {index.ep:.4f}, imperfection Ep/(rho50 - 1) = {index.imperfection:.4f}.\n"
    )
    if curve.notes:
        parts.append(f"Notes: {_rst_text(curve.notes)}\n")
    if figure:
        parts.append(
            f".. figure:: {figure}\n   :alt: {curve.id} density curves\n\n"
            f"   Partition to sinks of {curve.id} with the cut density {DENSITY_FIGURE_CUT:g} "
            + ("and Ep 0.04 for three pairs of limits.\n" if curve.has_limits else "for three probable errors.\n")
        )
    parts.append(f"Citation: {_rst_text(curve.citation)}\n")
    return "\n".join(parts)


def density_catalogue(curves=None, *, figure_dir: Path | None = None, figure_prefix: str = "formulas") -> str:
    """The density section of the catalogue over ``curves`` (default every registry density curve)."""
    from tromplab.density.registry import DENSITY_CURVES

    curves = tuple(DENSITY_CURVES if curves is None else curves)
    parts = [
        _title("Density partition curves (gravity separators)", "="),
        f"The partition to the sinks P(rho) of relative density rho of dense-medium and gravity separators "
        f"({len(curves)} curves, generated from ``tromplab.density.registry.DENSITY_CURVES``): each plain curve is "
        "written with the cut density rho50 (P = 1/2) and the probable error Ep = (rho75 - rho25)/2 in density units; "
        "each has a variant with a light-end limit l and a heavy-end limit h, whose rho50 and Ep are read from P "
        "itself. Fitting, washability predictions and the size trend are in :doc:`../density`.\n",
    ]
    for curve in curves:
        figure = None
        if figure_dir is not None:
            draw_density_family(curve, Path(figure_dir) / f"density_{curve.id}.png")
            figure = f"{figure_prefix}/density_{curve.id}.png"
        parts.append(density_curve_section(curve, figure))
    return "\n".join(parts)


# --- the API reference ----------------------------------------------------------------
def public_names() -> list[str]:
    import tromplab

    return [name for name in tromplab.__all__ if name != "__version__"]


def module_members(module_name: str) -> list[str]:
    """Public functions and classes defined in ``module_name`` and not re-exported by ``tromplab``."""
    import tromplab

    module = importlib.import_module(module_name)
    exported = {id(getattr(tromplab, name)) for name in public_names()}
    declared = getattr(module, "__all__", None)
    names = []
    for name, obj in vars(module).items():
        if name.startswith("_") or (declared is not None and name not in declared):
            continue
        if not (inspect.isfunction(obj) or inspect.isclass(obj)) or getattr(obj, "__module__", None) != module_name:
            continue
        if id(obj) in exported:
            continue
        names.append(name)
    return names


def package_modules() -> list[str]:
    """Every module of the ``tromplab`` package that a user may import (not ``__main__``)."""
    import tromplab

    names = []
    for info in pkgutil.walk_packages(tromplab.__path__, prefix="tromplab."):
        leaf = info.name.rsplit(".", 1)[-1]
        if leaf == "__main__" or any(part.startswith("_") for part in info.name.split(".")[1:]):
            continue
        names.append(info.name)
    return sorted(names)


def api_reference() -> str:
    """The API page: ``tromplab.__all__`` first, then each module's own public functions and classes."""
    import tromplab

    parts = [
        ".. This page is generated from tromplab.__all__ and the package's modules by docs/_ext/tromplab_docs.py.\n",
        _title("API reference", "#"),
        ".. currentmodule:: tromplab\n",
        "The public API is ``tromplab.__all__``: these names stay stable across releases.\n",
        _title("Public names (tromplab.__all__)", "="),
        f".. data:: __version__\n   :type: str\n\n   The installed version of tromplab ({tromplab.__version__}); "
        "kept in ``tromplab/_version.py`` only, which ``pyproject.toml`` reads.\n",
        ".. autosummary::\n   :toctree: api\n\n" + "\n".join(f"   {name}" for name in public_names()) + "\n",
        _title("Modules", "="),
        "The functions and classes each module of the package defines (names of ``tromplab.__all__`` "
        "are listed above only). Modules may move between layers; import from ``tromplab`` where you can.\n",
    ]
    for module_name in package_modules():
        members = module_members(module_name)
        if not members:
            continue
        parts.append(_title(module_name, "-"))
        parts.append(f".. currentmodule:: {module_name}\n")
        parts.append(".. autosummary::\n   :toctree: api\n\n" + "\n".join(f"   {name}" for name in members) + "\n")
    return "\n".join(parts)


# --- Sphinx -----------------------------------------------------------------------------
def _write_if_changed(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def write_pages(srcdir) -> None:
    """Write ``cli.rst``, ``formulas.rst`` (with figures) and ``api.rst`` into ``srcdir/generated``."""
    out = Path(srcdir) / GENERATED
    _write_if_changed(out / "cli.rst", cli_reference())
    catalogue = formula_catalogue(figure_dir=out / "formulas") + "\n" + density_catalogue(figure_dir=out / "formulas")
    _write_if_changed(out / "formulas.rst", catalogue)
    _write_if_changed(out / "api.rst", api_reference())


def _rewrite_readme_links(app, relative_path, parent_docname, content) -> None:
    """README sections included in docs/ pages: its links to ``docs/X.md`` become ``X.md``."""
    if Path(relative_path).name != "README.md":
        return
    text = content[0]
    text = re.sub(r"\]\(docs/([^)]+)\)", r"](\1)", text)
    content[0] = text


def setup(app):
    # config-inited: the pages exist before Sphinx lists the sources (autosummary's stubs need them)
    app.connect("config-inited", lambda app, config: write_pages(app.srcdir))
    app.connect("include-read", _rewrite_readme_links)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
