"""``jaxmpm study NAME``: run one of the studies in ``jaxmpm.studies`` and write its figures and tables."""

import importlib

import jax

from ._common import writable_folder

STUDIES = {
    "talk": "talk",
    "convergence": "convergence",
    "work-precision": "work_precision",
    "stability": "stability",
    "multid": "multid",
    "detonation": "detonation",
    "blast": "blast",
    "gurney": "gurney",
}
"""The name on the command line of each study, and its module in ``jaxmpm.studies``."""

RELEASING = ("convergence", "stability")
"""Studies that compile a new program for each group of runs and call ``release()`` when a group is
done. The command drops JAX's caches there: every compiled XLA CPU program holds about 265 memory
maps, and past the process's limit (``vm.max_map_count``, 65,530 by default) compiling the next one
crashes."""


def add_parser(subparsers) -> None:
    """Add the ``study`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser("study", help="run a study and write its figures and tables")
    p.add_argument(
        "name",
        choices=list(STUDIES),
        help="talk: the 2013 MPM workshop comparison; convergence: observed orders on the verification "
        "ladder; work-precision: error against run time; stability: the stiff and extreme map; multid: 2D "
        "and 3D (first step, axis-aligned orders, blast domain gaps, a 100k-particle 2D run); detonation: "
        "the planar detonation's F by interpolator, its convergence behind the front and the peak pressure "
        "against P_CJ by burn model; blast: the 2D disk and 3D sphere gas charges against their radial "
        "reference by interpolator and remedy (breakdowns, errors, smoothness) and the refined best "
        "CPDI; gurney: a charge driving its metal tube in 2D, the tube's velocity against Gurney's by "
        "resolution, interpolator and strength",
    )
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--small", action="store_true", help="a quick reduced version (for tests)")
    p.set_defaults(handler=command)


def command(args) -> int:
    """Run the study ``args.name`` into ``args.out``.

    Args:
        args: the parsed command line.

    Returns:
        The exit status, 0.

    Raises:
        UsageError: ``--out`` cannot be written (found before the study starts).
    """
    writable_folder(args.out, "--out")
    study = importlib.import_module(f"jaxmpm.studies.{STUDIES[args.name]}")
    options = dict(release=jax.clear_caches) if args.name in RELEASING else {}
    study.main(out=args.out, small=args.small, **options)
    return 0
