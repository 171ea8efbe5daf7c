"""Names given by users are shown as written: never read as markup in plots, file names or
the comments of written files, and never refused for the characters markup uses."""
from __future__ import annotations

import matplotlib
import pytest
import yaml

from bag_helpers import record_emergency_stop
from campaigns.campaign_helpers import write_campaign
from ltd_brake_ros.analysis.plots import write_plots
from ltd_brake_ros.analysis.report import analyse
from ltd_brake_ros.inputs import consist_from_mapping

matplotlib.use("Agg")

#: Mathtext that does not parse (an unknown command between two dollars), HTML, an
#: underscore that matplotlib would take as "leave out of the legend", a path.
NAME = r"_cost $5 \nosuchcommand$ <b>&amp; ../x"


@pytest.fixture
def drawn(monkeypatch):
    """Every text matplotlib draws, with whether it was read as mathtext."""
    from matplotlib.text import Text

    seen = []
    draw = Text.draw

    def spy(self, renderer):
        seen.append((self.get_text(), self._preprocess_math(self.get_text())[1]))
        return draw(self, renderer)

    monkeypatch.setattr(Text, "draw", spy)
    return seen


def test_a_report_draws_the_consist_name_as_written(tmp_path, drawn):
    consist = consist_from_mapping({"name": NAME, "vehicles": [
        {"type": "E402B"}, {"type": "Shimmns", "count": 4, "mass_t": 80.0}]}, "names")
    record_emergency_stop(tmp_path / "run", consist, 40.0)
    paths = write_plots(analyse(tmp_path / "run"), tmp_path / "report")
    assert len(paths) >= 4 and all(p.stat().st_size > 1000 for p in paths)
    titled = [(text, math) for text, math in drawn if NAME in text]
    assert len(titled) >= 4  # each plot's title names the train, whole
    assert not any(math for _, math in titled)


def test_a_campaign_report_draws_and_files_names_as_written(tmp_path, drawn):
    from ltd_brake_ros.analysis.campaign_report import campaign_report
    from ltd_brake_ros.inputs.campaign import load_campaign
    from ltd_brake_ros.studies.campaign_exec import run_campaign

    path = write_campaign(tmp_path, name="names", runs=4, batch=2)
    doc = yaml.safe_load(path.read_text())
    doc["name"] = "_$x$ & <i>"
    doc["manoeuvres"][0]["name"] = "stop/../../escape $y$"
    path.write_text(yaml.safe_dump(doc))
    run_campaign(load_campaign(path), tmp_path / "out")
    plots = tmp_path / "plots"
    rep = campaign_report(tmp_path / "out", plots=plots)
    files = sorted(p.name for p in plots.iterdir())
    assert files and len(files) == len(rep["plots"])
    assert all(f.startswith(("cdf_stop_", "hist_stop_")) and "/" not in f for f in files)
    assert not (tmp_path / "escape").exists()
    labels = [text for text, math in drawn if text == "_$x$ & <i>"]
    assert len(labels) >= len(files)  # every plot's legend names the campaign, whole
    assert not any(math for text, math in drawn if "$" in text)


def test_a_parameter_file_comment_cannot_be_broken_out_of():
    from ltd_brake_ros.outputs import one_line

    line = one_line("# --consist train.yaml\nk0: 99\u202e")
    assert "\n" not in line and "\\n" in line and "\\u202e" in line
    assert yaml.safe_load(line) is None  # a comment, all of it
