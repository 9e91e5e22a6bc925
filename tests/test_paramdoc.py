"""Parameter files as typed documents (mrta_zenoh.paramdoc): sized arrays to lists, shape and
value errors naming file, line and the file's own key path, with "did you mean"."""

import pytest
import msgspec

from mrta_zenoh import paramdoc
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.limits import RATE
from mrta_zenoh.paramdoc import Duration, Id, Rate, Text, sized, whole, within


class Item(msgspec.Struct, forbid_unknown_fields=True):
    topic_name: Text
    period: Duration = 1.0


class Inner(msgspec.Struct, forbid_unknown_fields=True):
    limit: whole(1, 10) = 3
    items: sized(Item, "item") = []


class Top(msgspec.Struct, forbid_unknown_fields=True):
    spin_rate: Rate
    items: sized(Item, "item")
    inner: Inner | None = None
    task: Id = "t"
    gain: within(RATE) = 1.0


GOOD = """\
spin_rate: 2
items:
  size: 2
  item0:
    topic_name: odom
  item1:
    topic_name: sonar
    period: 0.5
inner:
  items:
    size: 1
    item0: {topic_name: odom}
"""


def load(tmp_path, text):
    f = tmp_path / "p.yaml"
    f.write_text(text)
    return paramdoc.load(f, Top, "a test file")


def error(tmp_path, text) -> str:
    with pytest.raises(ConfigError) as info:
        load(tmp_path, text)
    return str(info.value)


def test_sized_arrays_become_lists_and_paths_lead_back_to_the_file(tmp_path):
    d = load(tmp_path, GOOD)
    assert d.value.spin_rate == 2.0 and isinstance(d.value.spin_rate, float)
    assert [i.topic_name for i in d.value.items] == ["odom", "sonar"]
    assert d.value.items[1].period == 0.5 and d.value.inner.items[0].topic_name == "odom"
    assert d.origin(("items", 1, "period")) == ("items", "item1", "period")
    assert d.origin(("inner", "items", 0)) == ("inner", "items", "item0")
    assert d.where(("items", 1, "period")).endswith("p.yaml:8")
    assert "p.yaml:7: 'items/item1/topic_name': x" in str(d.error(("items", 1, "topic_name"), "x"))


@pytest.mark.parametrize("old,new,line,key,text", [
    ("spin_rate: 2", "spin_rate: 0", 1, "spin_rate", "spin_rate must be > 0, got 0"),
    ("spin_rate: 2", "spin_rate: 5000", 1, "spin_rate",
     "spin_rate must be between 0.01 and 1000 Hz (a tick every 100 s to 1 kHz), got 5000"),
    ("spin_rate: 2", "spin_rate: .nan", 1, "spin_rate", "spin_rate must be a finite number"),
    ("spin_rate: 2", "spin_rate: fast", 1, "spin_rate", "spin_rate must be a number, got 'fast'"),
    ("spin_rate: 2", "spin_rate: true", 1, "spin_rate", "spin_rate must be a number, got True"),
    ("spin_rate: 2", "spin_rte: 2", 1, "spin_rte",
     "unknown key 'spin_rte' (did you mean 'spin_rate'?)"),
    ("spin_rate: 2\n", "", None, "spin_rate", "missing mandatory key 'spin_rate'"),
    ("    period: 0.5", "    perod: 0.5", 8, "items/item1/perod",
     "unknown key 'perod' (did you mean 'period'?)"),
    ("    period: 0.5", "    period: -1", 8, "items/item1/period", "period must be > 0, got -1"),
    ("    topic_name: sonar", "    topic_name: ' '", 7, "items/item1/topic_name",
     "topic_name must be a non-empty string"),
    ("  size: 2", "  size: 3", 2, "items", "size is 3 but 'item2' is missing"),
    ("  size: 2", "  size: 1", 6, "items/item1", "unexpected key 'item1' (size is 1)"),
    ("inner:\n", "inner:\n  limit: 11\n", 10, "inner/limit",
     "limit must be a whole number in [1, 10], got 11"),
    ("inner:\n", "inner:\n  limit: 2.5\n", 10, "inner/limit",
     "limit must be a whole number in [1, 10], got 2.5"),
    ("inner:\n", "inner:\n  limt: 2\n", 10, "inner/limt",
     "unknown key 'limt' (did you mean 'limit'?)"),
    ("    item0: {topic_name: odom}", "    item0: {topic_nam: odom}", 12,
     "inner/items/item0/topic_nam", "(did you mean 'topic_name'?)"),
    ("spin_rate: 2", "spin_rate: 2\ntask: a/b", 2, "task", "task 'a/b' must be one key chunk"),
    ("inner:\n  items:", "inner: 3\nx:\n  items:", 9, "inner", "expected a mapping, got int"),
])
def test_a_bad_value_names_file_line_and_the_files_own_key(tmp_path, old, new, line, key, text):
    assert old in GOOD
    msg = error(tmp_path, GOOD.replace(old, new, 1))
    where = f"p.yaml:{line}: " if line else "p.yaml: "
    assert where + f"'{key}': " in msg and text in msg, msg


def test_a_default_is_not_checked_but_a_written_value_is(tmp_path):
    class Named(msgspec.Struct, forbid_unknown_fields=True):
        name: Text = ""
    f = tmp_path / "n.yaml"
    f.write_text("{}\n")
    assert paramdoc.load(f, Named, "x").value.name == ""
    f.write_text("name: ''\n")
    with pytest.raises(ConfigError, match="name must be a non-empty string"):
        paramdoc.load(f, Named, "x")


def test_a_top_level_that_is_not_a_mapping_names_the_file_kind(tmp_path):
    with pytest.raises(ConfigError, match="a test file must be a mapping"):
        load(tmp_path, "- 1\n")
