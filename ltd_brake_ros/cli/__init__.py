"""``ltd-brake``: the command line, one module per verb over the library.

Each verb module (``simulate``, ``validate``, ``calibrate``, ``report``, ``recover``) has

``add_parser(subparsers) -> argparse.ArgumentParser``
    adds the verb, its options and help (units and signs), and sets ``func=run``;
``run(args: argparse.Namespace) -> int``
    calls the library, prints, returns the exit status; bad input raises
    :class:`~ltd_brake_ros.inputs.InputError`.

:mod:`.main` assembles the parser and is the one place that turns errors into a line on
stderr; :mod:`.options` holds the options several verbs share.
"""
