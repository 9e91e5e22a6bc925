"""Generators never write what `mrta instance validate` refuses (issue 51.5): the delivery and
Solomon generators' text, over parameters and files Hypothesis draws, either reads back as a
valid instance or is refused with a ConfigError before anything is written; a Solomon file with
NaN coordinates is refused naming the customer; and whatever a generator makes, the verb reads
its text back before writing it (a generator's bug is one line, exit 2, no file)."""

from __future__ import annotations

from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrta_delivery.instance import document_of
from mrta_delivery.instances import GENERATOR, DeliveryGeneratorParams
from mrta_delivery.solomon import GENERATOR as SOLOMON, SolomonParams
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.yamlfile import parse_yaml

HYPOTHESIS = settings(max_examples=40, deadline=None, derandomize=True,
                      suppress_health_check=[HealthCheck.function_scoped_fixture,
                                             HealthCheck.too_slow])


def valid_or_refused(gen, params, seed: int = 0) -> None:
    """The generator's own text (not the verb's check) reads back as a valid instance, or the
    generator refuses with a ConfigError."""
    try:
        text = gen.generate(params, seed)
    except ConfigError:
        return
    document_of(parse_yaml(text, "generated.yaml"))  # raises what validate would say


pair = st.tuples(st.floats(0.0, 30.0), st.floats(0.0, 30.0)).map(sorted).map(tuple)


@HYPOTHESIS
@given(robots=st.integers(1, 12), tasks=st.integers(1, 25), walls=st.integers(0, 3),
       room=st.tuples(st.floats(2.0, 30.0), st.floats(2.0, 30.0)),
       rate=st.sampled_from([0.0, 0.1, 2.0]), share=st.sampled_from([0.0, 0.5, 1.0]),
       width=pair, slack=pair, service=pair, windows=st.sampled_from(["hard", "soft"]),
       seed=st.integers(0, 5))
def test_the_delivery_generator_writes_only_valid_instances(robots, tasks, walls, room, rate,
                                                            share, width, slack, service,
                                                            windows, seed):
    params = DeliveryGeneratorParams(robots=robots, tasks=tasks, walls=walls, room=room,
                                     rate=rate, window_share=share, window_width=width,
                                     window_slack=slack, service=service, windows=windows)
    valid_or_refused(GENERATOR, params, seed)


def solomon_text(depot, customers) -> str:
    rows = [f"{k:5d} {x:9g} {y:9g} 10 {ready:9g} {ready + 200:9g} 10"
            for k, (x, y, ready) in enumerate([(*depot, 0)] + customers)]
    return ("MINI\n\nVEHICLE\nNUMBER     CAPACITY\n  25         200\n\nCUSTOMER\n"
            "CUST NO.  XCOORD.   YCOORD.    DEMAND   READY TIME  DUE DATE   SERVICE   TIME\n\n"
            + "\n".join(rows) + "\n")


coordinate = st.integers(0, 100)


@HYPOTHESIS
@given(depot=st.tuples(coordinate, coordinate),
       customers=st.lists(st.tuples(coordinate, coordinate, st.integers(0, 500)), min_size=1,
                          max_size=12),
       robots=st.integers(1, 9), room=st.sampled_from([(12.0, 8.0), (20.0, 20.0), (6.0, 4.0)]))
def test_the_solomon_generator_writes_only_valid_instances(tmp_path, depot, customers, robots,
                                                           room):
    f = tmp_path / "s.txt"
    f.write_text(solomon_text(depot, customers))
    valid_or_refused(SOLOMON, SolomonParams(file=str(f), robots=robots, room=room))


def test_three_robots_round_a_depot_at_the_edge_stand_clear_of_the_wall(tmp_path):
    """The newcomer's case: a depot at the bottom edge of the customers' box put the third robot
    on the ring 0.13 m from the wall (`--robots 3 --tasks 10`, refused by validate)."""
    f = tmp_path / "s.txt"
    f.write_text(solomon_text((40, 50), [(45, 68, 0), (30, 70, 0), (60, 56, 0), (50, 60, 0)]))
    out = tmp_path / "s.yaml"
    r = CliRunner().invoke(cli, ["instance", "generate", "solomon", "--file", str(f),
                                 "--robots", "3", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert CliRunner().invoke(cli, ["instance", "validate", str(out)]).exit_code == 0


def test_a_solomon_file_with_nan_coordinates_is_refused_naming_the_customer(tmp_path):
    f = tmp_path / "s.txt"
    f.write_text(solomon_text((40, 50), [(45, 68, 0)]).replace("    45 ", "   nan "))
    out = tmp_path / "s.yaml"
    r = CliRunner().invoke(cli, ["instance", "generate", "solomon", "--file", str(f), "-o",
                                 str(out)])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
    assert f"{f}:11: 'nan' is not a finite number" in r.output
    assert not out.exists()


def test_the_verb_reads_a_generators_text_back_before_writing_it(tmp_path, monkeypatch):
    good = GENERATOR.generate
    monkeypatch.setattr(type(GENERATOR), "generate",
                        lambda self, p, seed: good(p, seed).replace("  t1:", "  't 1':"))
    out = tmp_path / "x.yaml"
    r = CliRunner().invoke(cli, ["instance", "generate", "delivery", "-o", str(out)])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
    assert "generator delivery made an instance validate would refuse" in r.output
    assert "'tasks/t 1': task id 't 1' is not one key chunk" in r.output
    assert not out.exists()
