"""Campaign result files describe themselves: units and descriptions in the Parquet schema."""
from __future__ import annotations

import json

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from campaign_helpers import write_campaign

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs.campaign import fittable_parameters, load_campaign
from ltd_brake_ros.studies.campaign import SCHEMA_VERSION, run_batch, schema_of
from ltd_brake_ros.studies.campaign_exec import read_results, run_campaign

#: Unit a column's name ends with -> the unit its metadata must give.
SUFFIX_UNITS = {"_kN": "kN", "_m": "m", "_s": "s", "_t": "t", "_kmh": "km/h", "_percent": "%"}


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """The small campaign run serially (4 trains, 2 batches): campaign and results folder."""
    folder = tmp_path_factory.mktemp("schema")
    c = load_campaign(write_campaign(folder, runs=4, batch=2))
    run_campaign(c, folder / "out")
    return c, folder / "out"


def batch_file(out):
    return out / "batches" / "batch-0000000.parquet"


def test_every_column_of_a_batch_file_has_its_unit_and_description(results):
    c, out = results
    schema = pq.read_schema(batch_file(out))
    assert schema.names == schema_of(c).names
    for field in schema:
        meta = field.metadata or {}
        assert meta.get(b"description", b"").strip(), field.name
        kind = field.type.value_type if pa.types.is_list(field.type) else field.type
        if pa.types.is_integer(kind) or pa.types.is_floating(kind):
            assert b"unit" in meta, field.name
        if pa.types.is_floating(kind):  # a measured quantity or a ratio, never unitless text
            assert meta[b"unit"], field.name
        unit = meta.get(b"unit", b"").decode()
        for suffix, expected in SUFFIX_UNITS.items():
            if field.name.endswith(suffix):
                assert unit == expected, field.name
    meta = schema.metadata
    assert meta[b"ltd_brake_ros.schema_version"] == str(SCHEMA_VERSION).encode() == b"3"
    units = json.loads(meta[b"ltd_brake_ros.units"])
    assert list(units) == schema.names
    assert all(units[f.name] == f.metadata[b"unit"].decode() for f in schema)
    # the writer's own keys stay beside them
    assert meta[b"ltd_brake_ros.batch"] == b"0" and meta[b"ltd_brake_ros.campaign_digest"]


def test_units_and_descriptions_say_what_the_values_mean(results):
    c, out = results
    schema = pq.read_schema(batch_file(out))
    unit = {f.name: f.metadata[b"unit"].decode() for f in schema}
    text = {f.name: f.metadata[b"description"].decode() for f in schema}
    assert unit["speed_kmh"] == "km/h" and unit["braked_weight_percent"] == "%"
    assert unit["mean_adhesion"] == "-" and unit["wagons"] == "-"
    assert unit["status"] == unit["run_id"] == unit["draft_ok"] == ""
    assert "buff negative" in text["peak_buff_kN"]
    assert "from 1 behind the head" in text["peak_buff_coupler"]
    assert "isolated" in text["wagon_brakes"]
    # an uncertain parameter: the unit and meaning of the model parameter it sets
    _, fit = fittable_parameters()["k0"]
    assert unit["k0"] == fit.unit and fit.meaning.lower() in text["k0"].lower()


def test_results_keep_their_values_and_columns(results):
    c, out = results
    # a batch's table carries the schema, metadata and all, that the file then holds
    assert run_batch(c, 1).schema.equals(schema_of(c), check_metadata=True)
    table = read_results(out)[1]
    assert table.schema.remove_metadata().equals(schema_of(c).remove_metadata())
    assert table.num_rows == c.runs and set(table["status"].to_pylist()) == {"ok"}


@pytest.mark.parametrize("which", ["batch", "folder", "campaign"])
def test_schema_action_lists_every_column(results, capsys, which):
    c, out = results
    path = {"batch": batch_file(out), "folder": out, "campaign": c.source}[which]
    assert main(["campaign", "schema", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "schema version 3" in lines[0] and lines[1].split() == [
        "column", "type", "unit", "description"]
    listed = [line.split()[0] for line in lines[2:]]
    assert listed == schema_of(c).names
    row = next(line for line in lines if line.startswith("peak_buff_kN "))
    assert row.split()[1:3] == ["double", "kN"] and "buff negative" in row


def test_schema_action_prints_json(results, capsys):
    c, out = results
    assert main(["campaign", "schema", str(batch_file(out)), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["schema_version"] == 3
    assert [col["name"] for col in got["columns"]] == schema_of(c).names
    col = next(col for col in got["columns"] if col["name"] == "stopping_distance_m")
    assert col["type"] == "double" and col["unit"] == "m" and col["description"]


def test_schema_action_refuses_what_is_not_a_campaign_result(tmp_path, capsys):
    other = tmp_path / "other.parquet"
    pq.write_table(pa.table({"x": [1.0]}), other)
    text = tmp_path / "notes.txt"
    text.write_text("not parquet")
    for path, reason in ((other, "not a batch file"), (text, "not a readable Parquet file"),
                         (tmp_path / "missing.parquet", "no such file")):
        assert main(["campaign", "schema", str(path)]) == 2
        assert reason in capsys.readouterr().err
