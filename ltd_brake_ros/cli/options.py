"""Options several verbs share: the model files, the run specification, scenario lists.

Building a parser imports nothing else of the package (``ltd-brake --help`` stays quick); the
inputs and the physics are imported when a verb runs.
"""
from __future__ import annotations

import argparse

CONVENTIONS = """\
units and signs:
  speeds in km/h on the command line, SI (m, s, N) in files and JSON unless the key says
  otherwise (e.g. peak_draft_kN); coupler 1 is the coupler behind the head vehicle; draft
  (tension) forces are positive, buff (compression) forces negative; the stopping distance is
  the head's travel from the emergency command to standstill (every vehicle < 1 mm/s).
"""

#: Command-line option of each run-spec input, for error messages.
RUN_SPEC_OPTIONS = {"consist": "--scenario/--consist", "speed_kmh": "--speed-kmh",
                    "brake_params": "--params", "coupler_lut": "--lut", "track": "--track"}


def add_model_options(p: argparse.ArgumentParser) -> None:
    """Add ``--params``, ``--lut``, ``--v-th-mm-s`` and ``--step-s``.

    Parameters
    ----------
    p : argparse.ArgumentParser
    """
    p.add_argument("--params", metavar="FILE",
                   help="brake-parameter YAML (model: and its fields, e.g. t_app_s, v_air_m_s, "
                        "t_fill_s, k0); default for a run: the paper's empirical model "
                        "(brake_params/paper.yaml, Table 3) for trains up to 500 m, the UIC "
                        "brake pipe (brake_params/uic_brake_pipe.yaml) beyond; validate and "
                        "calibrate: paper.yaml")
    p.add_argument("--lut", metavar="FILE",
                   help="coupler LUT YAML (deflection_mm, loading_kN, unloading_kN); default: "
                        "the reconstructed buffer-hook table config/couplers/buffer_hook_pugi.yaml")
    p.add_argument("--v-th-mm-s", type=float, metavar="MM_S",
                   help="Eq. 3 threshold speed between loading and unloading curves [mm/s] "
                        "(default: the LUT file's, 0.1)")
    p.add_argument("--step-s", type=_step, default=0.01, metavar="S",
                   help="nominal integration step [s], a whole fraction of the 0.1 s chunks "
                        "the runs advance in (e.g. 0.005, 0.01, 0.02, 0.025, 0.05; default "
                        "0.01)")


#: The shortest chunk a command-line run advances in [s] (recorded and sampled runs); the
#: others are whole multiples of it.
SHORTEST_CHUNK_S = 0.1


def _step(text: str) -> float:
    """``--step-s``: a number of seconds that divides :data:`SHORTEST_CHUNK_S` into whole
    steps (argparse names the option in its error)."""
    try:
        step = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not (1e-5 <= step <= 0.1):
        raise argparse.ArgumentTypeError(f"{text} s: a step must be between 1e-05 and 0.1 s")
    k = round(SHORTEST_CHUNK_S / step)
    if abs(SHORTEST_CHUNK_S - k * step) > 1e-6 * step:
        raise argparse.ArgumentTypeError(
            f"{text} s does not divide the {SHORTEST_CHUNK_S:g} s chunks the runs advance in "
            "into whole steps (others would change the results): e.g. 0.005, 0.01, 0.02, "
            "0.025 or 0.05")
    return step


def add_run_spec_options(p: argparse.ArgumentParser) -> None:
    """Add the options of one run: train, initial speed, model files, track.

    ``--scenario``, ``--consist``, ``--speed-kmh``, the model options of
    :func:`add_model_options`, ``--tolerance-m-s``, ``--track`` and ``--start-chainage-m``;
    read them back with :func:`run_spec`.

    Parameters
    ----------
    p : argparse.ArgumentParser
    """
    p.add_argument("--scenario", metavar="N",
                   help="run N of the paper's Tables 1-2 (1-12): composition and initial speed")
    p.add_argument("--consist", metavar="FILE",
                   help="consist YAML (vehicles from the head); overrides the scenario's train")
    p.add_argument("--speed-kmh", type=float, metavar="KMH",
                   help="initial speed [km/h] (default: the scenario's, else 100)")
    add_model_options(p)
    p.add_argument("--tolerance-m-s", type=float, metavar="M_S",
                   help="local error allowed per integration step in each vehicle's speed "
                        "[m/s]: steps whose error estimate exceeds it are taken in shorter "
                        "sub-steps; 0 takes fixed steps of --step-s (default 0.001)")
    p.add_argument("--track", metavar="FILE",
                   help="track profile, YAML (sections: from_m, gradient_permille uphill "
                        "positive, radius_m) or CSV (chainage_m,gradient_permille,radius_m); "
                        "default: level straight track")
    p.add_argument("--start-chainage-m", type=float, metavar="M",
                   help="chainage of the head's front at t = 0 [m] (default: the track file's)")


def load_model(args: argparse.Namespace):
    """Brake parameters and coupler table named by :func:`add_model_options`.

    Parameters
    ----------
    args : argparse.Namespace

    Returns
    -------
    tuple of (BrakeParams, CouplerLUT)
    """
    from ..inputs import load_brake_params, load_coupler_lut

    return load_brake_params(args.params), load_coupler_lut(args.lut, args.v_th_mm_s)


def run_spec(args: argparse.Namespace):
    """Resolve the options of :func:`add_run_spec_options` with the one run-spec resolver.

    Parameters
    ----------
    args : argparse.Namespace

    Returns
    -------
    ltd_brake_ros.run_spec.RunSpec

    Raises
    ------
    InputError
        A bad file (naming the file and field) or a bad option (naming the option).
    """
    from ..inputs import InputError
    from ..run_spec import RunSpecError, resolve_run_spec

    try:
        return resolve_run_spec(args.consist, scenario=args.scenario, speed_kmh=args.speed_kmh,
                                params_file=args.params, lut_file=args.lut,
                                v_th_mm_s=args.v_th_mm_s, track_file=args.track,
                                start_chainage_m=args.start_chainage_m)
    except RunSpecError as exc:
        if exc.source != exc.input_name:
            raise  # a file's error names the file and field
        raise InputError("command line", RUN_SPEC_OPTIONS[exc.input_name], exc.reason) from None


def parse_scenarios(text: str, option: str = "--scenarios") -> list[int]:
    """Scenario numbers from a list such as ``1-6,9``.

    Parameters
    ----------
    text : str
        Comma-separated numbers and inclusive ranges ``a-b`` (a <= b).
    option : str, optional
        The option named in error messages.

    Returns
    -------
    list of int
        In the order given, each number once.

    Raises
    ------
    InputError
        Not numbers and ranges, a range that runs backwards, or nothing at all.
    """
    from ..inputs import InputError

    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        try:
            if "-" in part:
                a, b = part.split("-", 1)
                lo, hi = int(a), int(b)
                if hi < lo:
                    raise ValueError
                out.extend(range(lo, hi + 1))
            elif part:
                out.append(int(part))
        except ValueError:
            raise InputError("command line", option,
                             f"expected numbers and ranges like 1-6,9, got {text!r}") from None
    if not out:
        raise InputError("command line", option, "is empty")
    return list(dict.fromkeys(out))


def check_output_file(path: str, option: str, *, force: bool = False,
                      inputs: tuple = ()) -> None:
    """Refuse an output file that would replace an input or, without ``--force``, any file.

    Parameters
    ----------
    path : str
        The file the command is asked to write.
    option : str
        Its option, e.g. ``--out``.
    force : bool, optional
        ``--force``: an existing file (not an input) may be replaced.
    inputs : tuple of (str or None)
        Files the command reads (names as given; shipped names are resolved).

    Raises
    ------
    InputError
        One line naming the option and the reason.
    """
    from pathlib import Path

    from ..inputs import InputError
    from ..inputs.schema import resolve_config_path

    target = Path(path).expanduser()
    if not target.resolve().parent.is_dir():
        raise InputError("command line", option, f"the folder of {path} does not exist")
    if target.is_dir():
        raise InputError("command line", option, f"{path} is a folder; give a file name")
    for given in inputs:
        if not given:
            continue
        try:
            source = Path(resolve_config_path(given))
        except (InputError, OSError):
            continue
        if source.exists() and target.exists() and source.resolve() == target.resolve():
            raise InputError("command line", option, f"{path} is the input file {given}; "
                             "write the result to a new file (an input is never replaced)")
    if target.exists() and not force:
        raise InputError("command line", option, f"{path} exists; give a new file, or "
                         "--force to replace it")


def positive_int(value: int | None, option: str) -> int | None:
    """Check that an optional count (``--jobs``, ``--max-nfev``) is at least 1.

    Parameters
    ----------
    value : int or None
    option : str
        The option named in the error message.

    Returns
    -------
    int or None
        ``value`` unchanged.

    Raises
    ------
    InputError
        ``value`` is below 1.
    """
    if value is not None and value < 1:
        from ..inputs import InputError

        raise InputError("command line", option, f"must be at least 1, got {value}")
    return value


def json_by_key(document: dict) -> str:
    """A JSON object with one top-level key per line, its value compact.

    As readable as ``indent=2`` for a summary, and written by the json module's C encoder
    (indentation makes it fall back to Python: four times slower on a run's summary).

    Parameters
    ----------
    document : dict
        JSON-serialisable, string keys.

    Returns
    -------
    str
    """
    import json

    if not document:
        return "{}"
    encode = _SCALAR_JSON.get
    return "{\n" + ",\n".join(f"  {json.dumps(str(k))}: {encode(type(v), json.dumps)(v)}"
                              for k, v in document.items()) + "\n}"


def _finite_or_json(x: float) -> str:
    """A float as the json module writes it: its repr when finite."""
    import json

    return repr(x) if x - x == 0.0 else json.dumps(x)


#: JSON of the values a summary mostly holds, by exact type, written as the json module
#: writes them without the encoder it builds for every call.
_SCALAR_JSON = {float: _finite_or_json, int: repr, bool: lambda b: "true" if b else "false",
                type(None): lambda _: "null"}
