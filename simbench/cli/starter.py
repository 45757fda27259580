"""``simbench examples``: the example files, written out for a new user (an installed wheel has them
only inside the package)."""

from __future__ import annotations

import argparse

from simbench.api import write_examples


def add_arguments(ex: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench examples``."""
    ex.description = (
        "Write the files the getting-started steps use (a pose recording and its truth, studies, a "
        "cluster spec, two example estimators, the accepted baseline) into DIR, laid out as in the "
        "repository: examples/, studies/, reports/. Run the steps from DIR."
    )
    ex.add_argument("folder", metavar="DIR", help="where to write them (made if missing)")
    ex.add_argument("--force", action="store_true", help="replace files of the same names already there")
    ex.set_defaults(func=cmd_examples)


def cmd_examples(args: argparse.Namespace) -> int:
    """``simbench examples DIR``."""
    written = write_examples(args.folder, force=args.force)
    print(f"simbench examples: {len(written)} files in {args.folder}")
    for path in written:
        print(f"  {path}")
    return 0
