"""One SolveOptions travels from the command line to the search: each option works where it
is accepted, or is refused with a message that says why."""

from __future__ import annotations

import pytest

from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.problem import build_problem
from cuikslam.hypotheses.search import solve_unknown
from cuikslam.options import Level, SolveOptions
from cuikslam.simulate import simulate_paper


@pytest.fixture(scope="module")
def unknown_log():
    return simulate_paper(seed=0, unknown=True)[0]


def test_the_level_is_an_enum_and_auto_its_older_name_of_lp() -> None:
    from cuikslam.cli.main import build_parser

    parser = build_parser()
    for text, level in (("auto", Level.LP), ("lp", Level.LP), ("hull", Level.HULL)):
        args = parser.parse_args(["solve", "trip.jsonl", "--consistency", text])
        assert args.consistency is level
    assert parser.parse_args(["solve", "trip.jsonl"]).consistency is SolveOptions().consistency


def test_the_explorer_takes_the_search_options_whole(unknown_log) -> None:
    options = SolveOptions(consistency="hull", strengthen_during=3, threads=2, local_frame=False)
    explorer = Explorer.of(build_problem(unknown_log), options)
    assert explorer.level is Level.HULL and explorer.during == 3
    assert explorer.threads == 2 and explorer.local is None


def test_search_options_work_in_solve(unknown_log) -> None:
    """``max_nodes`` and ``local_frame`` were options of ``solve_unknown`` only."""
    import cuikslam

    cut = cuikslam.solve(unknown_log, max_nodes=1, certify_limit=0)
    assert not cut.complete
    same = cuikslam.solve(unknown_log, consistency="hull", local_frame=False, certify_limit=0)
    assert same.complete and same.hypotheses


def test_threads_reach_the_stronger_level_with_unknown_correspondence(
    unknown_log, monkeypatch
) -> None:
    import cuikslam.hypotheses.explorer as explorer_module

    seen = []
    real = explorer_module.strengthen

    def spy(*args, **kwargs):
        seen.append(kwargs.get("threads"))
        return real(*args, **kwargs)

    monkeypatch.setattr(explorer_module, "strengthen", spy)
    solve_unknown(unknown_log, consistency="lp", threads=1, strengthen_during=0)
    assert seen and set(seen) == {1}


@pytest.mark.parametrize("name", ["work_budget", "time_budget", "certify_limit"])
def test_the_search_refuses_the_options_of_the_stages_after_it(unknown_log, name) -> None:
    with pytest.raises(TypeError, match=rf"solve_unknown\(\) does not take {name}: "):
        solve_unknown(unknown_log, **{name: 1})


def test_a_mistyped_option_of_the_search_names_the_search(unknown_log) -> None:
    with pytest.raises(TypeError, match=r"solve_unknown\(\) .* 'max_node'; did you mean"):
        solve_unknown(unknown_log, max_node=3)
