"""``tromplab formulas``: the catalogue of separation-curve formulas (the nine of the paper,
the extended curves and the curves of other tools)."""

from __future__ import annotations

import textwrap


def add_formulas(commands, groups) -> None:
    formulas = commands.add_parser(
        "formulas", help="list the separation-curve formulas (the nine of the paper, then the extended curves)"
    )
    formulas.set_defaults(run=_run_formulas, imports=("tromplab.curves.formulas", "pandas", "scipy.special", "scipy.optimize"))


def _run_formulas(args) -> int:
    from ..curves.formulas import NAME_CLASHES, registry_table

    table = registry_table()
    for family, heading in (
        ("paper", "The nine formulas of Shuvalov et al. (2018)"),
        ("extended", "Extended curves (--extended)"),
        ("other", "Curves of other tools (--formulas other)"),
    ):
        print(f"{heading}:")
        for row in table[table["family"] == family].itertuples(index=False):
            extras = f", extras {row.extras}" if row.extras else ""
            print(
                textwrap.fill(
                    f"({row.equation}) {row.id}: phi = {row.formula}", width=98, initial_indent="  ", subsequent_indent="      "
                )
            )
            print(
                textwrap.fill(
                    f"shape {row.shape_name}{extras}; slope at the cut {row.slope_at_cut}",
                    width=98,
                    initial_indent="      ",
                    subsequent_indent="      ",
                )
            )
        print()
    print("Same name, different curve (docs/curves.md):")
    for clash in NAME_CLASHES:
        print(textwrap.fill(clash, width=98, initial_indent="  - ", subsequent_indent="    "))
    print()
    print("x = size / d_cut; phi = partition to the fine product. Corrections: docs/errata.md.")
    return 0
