"""Pilot tests of the events screen (`v`) and the plot screen (`p`): the answers checked against the
generator's truth file (captures/gcs_takeover.truth.json, written from what it sent) and pymavlink."""

from __future__ import annotations

import json

from mavscope.tui.app import create_app
from mavscope.tui.screens.events import EventsScreen
from mavscope.tui.screens.plot import PlotScreen
from tests.support.tui import CAPTURES, SIZE, ready, run, wait_for

TAKEOVER = CAPTURES / "gcs_takeover.pcap"
TRUTH = json.loads((CAPTURES / "gcs_takeover.truth.json").read_text(encoding="utf-8"))


def test_events_screen_lists_the_story_and_enter_jumps_to_the_frame() -> None:
    async def scenario() -> None:
        app = create_app(TAKEOVER)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            await pilot.press("v")
            assert isinstance(app.screen, EventsScreen)
            await wait_for(pilot, lambda: app.screen.result is not None)
            events = app.screen.result
            # the arming changes the generator put in the vehicle's HEARTBEATs, at the records it gives
            arming = [(e.frame, e.details["armed"]) for e in events if e.kind == "arming"]
            assert arming == [(a["record"], a["armed"]) for a in TRUTH["arming"]]
            table = app.screen.query_one("#events")
            assert table.row_count == len(events)
            row = next(i for i, e in enumerate(events) if e.kind == "arming" and not e.details["armed"])
            table.move_cursor(row=row)
            await pilot.press("enter")
            await pilot.pause()
            assert app.screen is app.screen_stack[0]
            assert app.index.row(app.packet_list.cursor_row).record == TRUTH["disarm_in_air"]["heartbeat_record"]

    run(scenario())


def test_plot_screen_plots_the_field_selected_in_the_tree() -> None:
    async def scenario() -> None:
        app = create_app(TAKEOVER)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            row = next(i for i in range(len(app.index)) if app.index.row(i).msgname == "GLOBAL_POSITION_INT")
            app.packet_list.move_to(row)
            await pilot.pause()
            await pilot.press("enter")  # to the tree, on the payload
            tree = app.tree
            node = tree.find(lambda it: it.name == "GLOBAL_POSITION_INT.relative_alt")
            tree.move_cursor(node)
            await pilot.pause()
            await pilot.press("p")
            assert isinstance(app.screen, PlotScreen)
            await wait_for(pilot, lambda: app.screen.result is not None)
            series = app.screen.plotter.series[0]
            # the generator sent GLOBAL_POSITION_INT at 5 Hz for 60 s; relative_alt from 0 to 25 m (mm)
            assert series.count == 300 and series.low == 0 and series.high == 25_000
            text = str(app.screen.query_one("#plot").render())
            assert "GLOBAL_POSITION_INT.relative_alt [mm]: 300 values" in text
            await pilot.press("escape")
            assert app.screen is app.screen_stack[0]

    run(scenario())


def test_plot_refuses_a_field_that_is_no_number() -> None:
    async def scenario() -> None:
        app = create_app(TAKEOVER)
        async with app.run_test(size=SIZE) as pilot:
            await ready(pilot)
            row = next(i for i in range(len(app.index)) if app.index.row(i).msgname == "STATUSTEXT")
            app.packet_list.move_to(row)
            await pilot.pause()
            await pilot.press("enter")
            node = app.tree.find(lambda it: it.name == "STATUSTEXT.text")
            app.tree.move_cursor(node)
            await pilot.pause()
            await pilot.press("p")
            await pilot.pause()
            assert app.screen is app.screen_stack[0]  # a notification, no screen

    run(scenario())
