"""``palpate memory``: train, cross-validate and show haptic memories (logic in
:mod:`palpate.core.perception.memory`)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.crossval import leave_one_out
from palpate.core.perception.memory import DEFAULT_MIN_EIG, HapticMemory
from palpate.core.perception.params_table import read_params_csv
from palpate.core.session.output_guard import check_output_file

CSV_HELP = "per-press parameters CSV: header with material,n1,n2,a1,a2 (any order, extra columns ignored)"


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``memory`` command group."""
    p = sub.add_parser("memory", help="train, cross-validate and show haptic memories",
                       description="Haptic memory: per-material Gaussians over (n1, n2) and (a1, a2), MAP rule.")
    p.set_defaults(func=lambda a: p.print_help() or 2)
    cmds = p.add_subparsers(dest="memory_command", metavar="SUBCOMMAND")

    t = cmds.add_parser("train", help="learn a haptic memory from per-press parameters and save it as JSON",
                        description="Learn a haptic memory from a per-press parameters CSV and save it as JSON.")
    t.add_argument("params", type=Path, help=CSV_HELP)
    t.add_argument("-o", "--output", type=Path, required=True, help="memory JSON file to write")
    t.add_argument("--force", action="store_true", help="overwrite an existing --output (never the params CSV)")
    _model_options(t)
    t.set_defaults(func=cmd_train)

    c = cmds.add_parser("crossval", help="leave-one-out confusion and mean posterior (seed 000 Table 6.7)",
                        description="Leave-one-out cross-validation: each press is classified by a memory "
                                    "trained on all the other presses. Rows are the true material.")
    c.add_argument("params", type=Path, help=CSV_HELP)
    c.add_argument("--json", action="store_true", help="print a JSON object instead of tables")
    _model_options(c)
    c.set_defaults(func=cmd_crossval)

    s = cmds.add_parser("show", help="print a saved haptic memory",
                        description="Print a saved haptic memory: materials, prior, means, covariances, "
                                    "regularisation and training size.")
    s.add_argument("memory", type=Path, help="memory JSON file written by 'palpate memory train'")
    s.add_argument("--json", action="store_true", help="print the memory's parameters as JSON")
    s.add_argument("--no-audit", action="store_true",
                   help="show a memory whose stored parameters do not match a re-fit of its training data (an "
                   "edited or corrupted file) instead of refusing it")
    s.set_defaults(func=cmd_show)


def _model_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--ddof", type=int, choices=(0, 1), default=0,
                   help="covariance divisor n - ddof: 0 reproduces seed 000 Table 6.6 (default), 1 is the sample "
                        "covariance (the one whose mean posterior matches Table 6.7)")
    p.add_argument("--prior", default=None, metavar="P1,P2,...",
                   help="prior weights, in the order materials first appear in the CSV (default: uniform)")
    p.add_argument("--min-eig", type=float, default=None,
                   help="smallest covariance eigenvalue relative to the largest, in units of each parameter's "
                        f"standard deviation; loading is added below that (default {DEFAULT_MIN_EIG:g})")


def _memory_kwargs(args: argparse.Namespace) -> dict:
    kwargs: dict = {"ddof": args.ddof}
    if args.prior is not None:
        try:
            kwargs["prior"] = [float(v) for v in args.prior.split(",")]
        except ValueError:
            raise ValidationError(
                f"--prior {args.prior!r}: expected comma-separated numbers, e.g. 0.5,0.3,0.2"
            ) from None
    if args.min_eig is not None:
        kwargs["min_eig"] = args.min_eig
    return kwargs


def _naming(path: Path, learn):
    """``learn()``, with a model error (too few presses of a material, a singular covariance) naming the table
    whose rows caused it."""
    try:
        return learn()
    except ValidationError as exc:
        raise ValidationError(f"{path}: {exc}") from None


def _table(header: list[str], rows: list[list[str]]) -> str:
    """Right-aligned columns except the first, separated by two spaces."""
    cells = [header] + rows
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = []
    for r in cells:
        parts = [r[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(r[1:], widths[1:], strict=True)]
        lines.append("  ".join(parts).rstrip())
    return "\n".join(lines)


def cmd_train(args: argparse.Namespace) -> int:
    check_output_file(args.output, inputs=[args.params], force=args.force, option="--output")
    params, labels, _ = read_params_csv(args.params)
    mem = _naming(args.params, lambda: HapticMemory(**_memory_kwargs(args)).fit(params, labels))
    mem.save(args.output)
    counts = {m: labels.count(m) for m in mem.materials}
    print(f"trained on {len(labels)} presses of {len(mem.materials)} materials "
          f"({', '.join(f'{m}: {n}' for m, n in counts.items())}), ddof={mem.ddof}")
    loaded = [f"{m} {part} {lam:.3g}" for m, r in mem.regularisation.items() for part, lam in r.items() if lam > 0]
    if loaded:
        print("regularised (relative diagonal loading): " + ", ".join(loaded))
    print(f"wrote {args.output}")
    return 0


def cmd_crossval(args: argparse.Namespace) -> int:
    params, labels, _ = read_params_csv(args.params)
    cv = _naming(args.params, lambda: leave_one_out(params, labels, **_memory_kwargs(args)))
    if args.json:
        print(json.dumps(cv.to_dict(), indent=1))
        return 0
    n_per = cv.counts.sum(axis=1).astype(int)
    print(f"Leave-one-out cross-validation of {args.params}: {len(labels)} presses, {len(cv.materials)} materials, "
          f"covariance ddof={args.ddof}, prior {args.prior or 'uniform'}")
    head = ["true \\ perceived", *cv.materials]
    print("\nMAP confusion (fraction of each true material's presses)")
    print(_table(head + ["presses", "accuracy"], [
        [m, *(f"{v:.2f}" for v in cv.confusion[i]), str(n_per[i]), f"{cv.confusion[i, i]:.2f}"]
        for i, m in enumerate(cv.materials)
    ]))
    print("\nMean posterior P(perceived | press)")
    print(_table(head, [[m, *(f"{v:.3f}" for v in cv.mean_posterior[i])] for i, m in enumerate(cv.materials)]))
    correct = int(np.trace(cv.counts))
    print(f"\nOverall accuracy: {correct}/{len(labels)} = {cv.accuracy:.3f}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    mem = HapticMemory.load(args.memory, audit=not args.no_audit)
    counts = [mem.training_labels.count(m) for m in mem.materials]
    if args.json:
        doc = mem.to_dict()
        doc.pop("training")
        doc["training_size"] = dict(zip(mem.materials, counts, strict=True))
        print(json.dumps(doc, indent=1))
        return 0
    print(f"Haptic memory {args.memory}: {len(mem.materials)} materials, trained on {len(mem.training_labels)} "
          f"presses, covariance ddof={mem.ddof}, min_eig={mem.min_eig:g}")
    print(_table(["material", "prior", "presses", "loading N", "loading A"], [
        [m, f"{mem.prior[k]:.3f}", str(counts[k]), f"{mem.regularisation[m]['N']:.3g}",
         f"{mem.regularisation[m]['A']:.3g}"]
        for k, m in enumerate(mem.materials)
    ]))
    for part, means, covs, (x1, x2) in (("N", mem.means_N, mem.covs_N, ("n1", "n2")),
                                         ("A", mem.means_A, mem.covs_A, ("a1", "a2"))):
        print(f"\n{part} = ({x1}, {x2}): mean and covariance")
        print(_table(["material", f"mu_{x1}", f"mu_{x2}", f"var_{x1}", f"cov_{x1}{x2}", f"var_{x2}"], [
            [m, *(f"{v:.6g}" for v in (*means[k], covs[k, 0, 0], covs[k, 0, 1], covs[k, 1, 1]))]
            for k, m in enumerate(mem.materials)
        ]))
    return 0
