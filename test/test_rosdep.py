"""``rosdep install --from-paths src`` on Ubuntu 24.04 (noble) with ROS 2 Jazzy: every key of
package.xml resolves, and what the keys install meets setup.py's minimums or the README names
the pip line that does.

Resolved the way rosdep resolves them, against the pinned copy of the rosdep database in
``test/rosdistro/`` (see its ``PIN``): a ROS package of the Jazzy distribution becomes the apt
package ``ros-jazzy-<name>``; a key of ``rosdep/base.yaml`` or ``rosdep/python.yaml`` its
``ubuntu`` rule (a list of apt packages, per release codename or ``*``, or ``pip`` packages).
"""
from __future__ import annotations

import functools
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from packaging.requirements import Requirement
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
DATABASE = ROOT / "test" / "rosdistro"
CODENAME = "noble"

#: Versions of the apt packages the Python keys name in Ubuntu 24.04 (noble), release pocket,
#: as the Ubuntu archive lists them (packages.ubuntu.com/noble) — not verified here: this
#: machine reaches Debian's archive, not Ubuntu's. Upstream version, Debian revision dropped.
NOBLE_VERSIONS = {
    "python3-numpy": "1.26.4",
    "python3-scipy": "1.11.4",
    "python3-yaml": "6.0.1",
    "python3-numba": "0.58.1",
    "python3-matplotlib": "3.6.3",
    "python3-tqdm": "4.66.2",
    "python3-pandas": "2.1.4",
    "python3-pytest": "7.4.4",
    "python3-pytest-timeout": "2.2.0",
    "python3-hypothesis": "6.98.15",
}
#: The Python distribution each apt package installs (its name on PyPI).
DISTRIBUTIONS = {"python3-yaml": "pyyaml", "python3-pytest-timeout": "pytest-timeout"}


def _package_keys() -> dict[str, list[str]]:
    """package.xml's rosdep keys by dependency kind (``exec_depend``, ``test_depend``)."""
    root = ET.parse(ROOT / "package.xml").getroot()
    keys: dict[str, list[str]] = {}
    for kind in ("depend", "build_depend", "buildtool_depend", "exec_depend", "test_depend"):
        keys[kind] = [e.text.strip() for e in root.iter(kind)]
    return keys


@functools.cache
def _database():
    def load(path: Path):  # libyaml's parser where PyYAML has it: 1 MB of YAML
        return yaml.load(path.read_text(), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))

    rules = {}
    for name in ("base.yaml", "python.yaml"):
        rules.update(load(DATABASE / "rosdep" / name))
    distribution = load(DATABASE / "jazzy" / "distribution.yaml")
    ros = set()
    for name, repo in distribution["repositories"].items():
        release = repo.get("release")
        if release and release.get("version"):
            ros.update(release.get("packages", [name]))
    return rules, ros


def resolve(key: str, rules: dict, ros: set) -> tuple[str, list[str]]:
    """What rosdep installs for ``key`` on ubuntu:noble with ROS 2 Jazzy.

    Returns
    -------
    (installer, packages)
        ``apt`` or ``pip``, and the packages.

    Raises
    ------
    LookupError
        The key is not in the database, or has no rule for Ubuntu noble.
    """
    if key in ros:
        return "apt", [f"ros-jazzy-{key.replace('_', '-')}"]
    if key not in rules:
        raise LookupError(f"{key}: not a key of the rosdep database")
    rule = rules[key].get("ubuntu") if isinstance(rules[key], dict) else None
    if isinstance(rule, dict) and not ({"pip", "apt", "packages"} & set(rule)):
        rule = rule.get(CODENAME, rule.get("*"))  # per codename
    if isinstance(rule, dict) and "pip" in rule:
        return "pip", list(rule["pip"]["packages"])
    if isinstance(rule, dict) and "apt" in rule:
        rule = rule["apt"]["packages"]
    if isinstance(rule, dict) and "packages" in rule:
        rule = rule["packages"]
    if not rule:
        raise LookupError(f"{key}: no rule for ubuntu:{CODENAME}")
    return "apt", list(rule)


def _minimums() -> dict[str, Requirement]:
    """setup.py's requirements (install_requires and the ``test`` extra) by name."""
    text = (ROOT / "setup.py").read_text()
    block = re.search(r"install_requires=\[(.*?)\]", text, re.S).group(1)
    test = re.search(r'"test": \[(.*?)\]', text, re.S).group(1)
    return {Requirement(r).name: Requirement(r)
            for r in re.findall(r'"([^"]+)"', block + test)}


def _pip_route() -> str:
    """The README's section on a ROS workspace, which names the pip line."""
    readme = (ROOT / "README.md").read_text()
    return readme[readme.index("**A ROS 2 Jazzy workspace**"):]


def test_every_key_of_package_xml_resolves_for_ubuntu_noble_and_jazzy():
    rules, ros = _database()
    keys = _package_keys()
    assert keys["exec_depend"] and keys["test_depend"]
    unresolved = []
    for key in sorted({k for ks in keys.values() for k in ks}):
        try:
            resolve(key, rules, ros)
        except LookupError as exc:
            unresolved.append(str(exc))
    assert not unresolved, unresolved
    # the interface packages the node serves and publishes are released for Jazzy
    for key in ("simulation_interfaces", "tf2_msgs", "nav_msgs"):
        assert key in keys["exec_depend"] and resolve(key, rules, ros)[0] == "apt"


def test_the_resolver_refuses_what_rosdep_refuses():
    rules, ros = _database()
    # the keys package.xml once declared that the database does not have
    for key in ("python3-xarray", "python3-salib-pip"):
        with pytest.raises(LookupError, match="not a key"):
            resolve(key, rules, ros)
    assert resolve("python3-rosbags-pip", rules, ros) == ("pip", ["rosbags"])
    assert resolve("rclpy", rules, ros) == ("apt", ["ros-jazzy-rclpy"])
    assert resolve("python3-tqdm", rules, ros) == ("apt", ["python3-tqdm"])  # per codename


def test_what_the_keys_install_meets_setup_py_or_the_readme_gives_the_pip_line():
    rules, ros = _database()
    keys = _package_keys()
    minimums = _minimums()
    route = _pip_route()
    covered = set()
    for key in keys["exec_depend"] + keys["test_depend"]:
        installer, packages = resolve(key, rules, ros)
        for package in packages:
            if installer == "pip":  # the newest release: any minimum is met
                covered.add(Requirement(package).name.lower())
                continue
            if not package.startswith("python3-"):
                continue
            name = DISTRIBUTIONS.get(package, package.removeprefix("python3-"))
            covered.add(name)
            assert package in NOBLE_VERSIONS, f"{package}: add its noble version"
            requirement = minimums.get(name)
            if requirement and Version(NOBLE_VERSIONS[package]) not in requirement.specifier:
                assert f'"{requirement}"' in route, (
                    f"{package} {NOBLE_VERSIONS[package]} does not meet {requirement}: the "
                    "README's ROS workspace section must give the pip line")
    # what no key brings (mcap comes with mcap-ros2-support) the README installs with pip
    for name, requirement in minimums.items():
        if name not in covered and name not in ("mcap", "zstandard", "lz4", "rosbags",
                                                "mcap-ros2-support"):
            assert f'"{requirement}"' in route, f"{requirement}: no key, and no pip line"
