"""``ltd-brake recover``: rewrite a recording cut short as a complete bag."""
from __future__ import annotations

import argparse


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``recover`` verb to ``ltd-brake`` (the verb contract: :mod:`ltd_brake_ros.cli`)."""
    ap = subparsers.add_parser(
        "recover", help="rewrite a recording cut short (e.g. SIGKILL) as a complete bag",
        description="Rewrite a recording whose recorder was killed into a complete, readable "
                    "bag folder: every complete chunk is kept.")
    ap.add_argument("src", help="bag folder or .mcap file")
    ap.add_argument("dst", nargs="?", help="new bag folder (default: SRC_recovered)")
    ap.set_defaults(func=run)
    return ap


def run(args: argparse.Namespace) -> int:
    """Recover the recording and say what was kept.

    Raises
    ------
    InputError
        The source is not a readable recording, the destination holds a bag, or it cannot be
        written (nothing half-written is left there).
    """
    from ..inputs import InputError
    from ..recording.reader import BagError
    from ..recording.recover import default_recover_destination, recover

    dst = args.dst or default_recover_destination(args.src)
    try:
        res = recover(args.src, dst)
    except BagError as exc:
        raise InputError("command line", "SRC", str(exc)) from None
    except FileExistsError as exc:
        raise InputError("command line", "DST", str(exc)) from None
    except OSError as exc:
        raise InputError("command line", "DST", f"cannot write {dst}: {exc}") from None
    if not res["complete"]:
        import sys

        print(f"ltd-brake recover: warning: {args.src} was not finished by its recorder "
              f"({res['stopped_at']}); every complete chunk is kept", file=sys.stderr)
    state = "was complete" if res["complete"] else f"ended early ({res['stopped_at']})"
    print(f"source {state}")
    print(f"recovered {res['messages']} messages from {res['chunks']} complete chunks "
          f"into {res['output']}")
    for topic, n in res["topics"].items():
        print(f"  {topic}: {n}")
    return 0
