"""The field view in a real browser: the demo graph runs, field_view serves it, headless Chromium
draws it, and what is drawn is checked against the graph's ground truth and the predictor.

The page's own account of what it drew (``window.fieldView.drawn``) is compared with the graph; the
ball's place is also checked in the screenshot's pixels, at the spot computed here from the field's
size and the page's default fit (the field and its run-off plus 0.2 m each side, centred), so a page
that mis-draws and mis-reports alike fails too. Screenshots go to test-artifacts/.
"""

from __future__ import annotations

import math
import os
import re
import sys
import time
from pathlib import Path

import pytest
from std_msgs.msg import Float64

from erforce_interfaces.wire import contract as c
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.demo.demo import LAUNCH_FILE, Director
from erforce_sim.in_process.scenes import KICKER, RECEIVER, default_scenes
from erforce_sim.view.headless_browser import Browser, chromium_missing

pytestmark = pytest.mark.integration

ARTIFACTS = Path(os.environ.get("ERFORCE_TEST_ARTIFACTS", Path(__file__).resolve().parents[2] / "test-artifacts"))
FIELD = FieldConfig.preset("division_b")
FIT_MARGIN_M = 0.2  # the page fits the walls plus this much each side


def require_chromium() -> None:
    """Skip where Chromium is not installed on a developer's machine; under CI (CI=true) fail."""
    missing = chromium_missing()
    if missing:
        why = f"{' and '.join(missing)} missing: apt-get install chromium chromium-driver (.ci/run does)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(why)
        pytest.skip(why)


@pytest.fixture
def graph_and_view(ros_graph):
    require_chromium()
    launch = ros_graph.start_launch(LAUNCH_FILE, real_time_factor="1.0", output="screen")
    director = Director(ros_graph.probe.node, RobotConfig(), ros_graph.probe.executor,
                        graph_alive=launch.alive, graph_hint="see the launch output below")
    view = ros_graph.start_node("erforce_sim", "field_view", params={"port": 0, "team_robot_ids": [RECEIVER]})
    url = view.wait_for_output(r"field view at (http://\S+)", timeout_s=60.0).group(1)
    assert director.spin_until(director.graph_ready, 120.0, "the graph"), launch.output()[-3000:]
    browser = Browser(1400, 800)
    try:
        browser.open(url)
        yield director, browser, view
    finally:
        browser.close()
        director.close()


def wait_drawn(director: Director, browser: Browser, condition, timeout_s: float, what: str) -> dict:
    """Spin the director (its series stay current) until the page's last drawn frame satisfies ``condition``."""
    deadline = time.monotonic() + timeout_s
    while True:
        director.spin_until(lambda: False, 0.05, "")
        drawn = browser.js("return window.fieldView && window.fieldView.drawn")
        if drawn and condition(drawn):
            return drawn
        if time.monotonic() > deadline:
            raise AssertionError(f"the page never drew {what}; last drawn: {drawn}")


def catch_up(director: Director, t_s: float) -> None:
    """Let the director's series reach simulated time ``t_s`` (the page may be ahead of it)."""
    s = director.series
    assert director.spin_until(lambda: s.ball_truth and s.ball_truth[-1][0] >= t_s and s.robot_truth
                               and s.robot_truth[-1][0] >= t_s and s.catch_points and s.catch_points[-1][0] >= t_s,
                               10.0, "the graph's messages")


def truth_at(rows: list, t_s: float) -> tuple:
    """The ground-truth row nearest to ``t_s``."""
    return min(rows, key=lambda row: abs(row[0] - t_s))


def canvas_pixel(browser: Browser, x_m: float, y_m: float) -> tuple[int, int]:
    """Where the page's default fit puts field point (x, y), in viewport pixels (computed here)."""
    left, top, width, height = browser.js(
        "const r = document.getElementById('field').getBoundingClientRect();"
        "return [r.left, r.top, r.width, r.height];")
    scale = min(width / (FIELD.length_m + 2 * FIELD.boundary_m + 2 * FIT_MARGIN_M),
                height / (FIELD.width_m + 2 * FIELD.boundary_m + 2 * FIT_MARGIN_M))
    return round(left + width / 2 + x_m * scale), round(top + height / 2 - y_m * scale)


def check_follow_zoom_and_fit(browser: Browser, drawn: dict) -> None:
    """Click robot_1: its numbers show. Wheel: zoom by exp(-deltaY * 0.0015) about the cursor, whose field
    point stays put. Double-click: the default fit again."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    canvas = browser.driver.find_element(By.ID, "field")
    width, height = browser.js("const r = arguments[0].getBoundingClientRect(); return [r.width, r.height];", canvas)
    px, py = drawn["robot_px"][str(KICKER)]
    ActionChains(browser.driver).move_to_element_with_offset(canvas, round(px - width / 2),
                                                             round(py - height / 2)).click().perform()
    deadline = time.monotonic() + 10.0
    while browser.js("return document.getElementById('followtitle').textContent") != f"Robot {KICKER} (ours)":
        assert time.monotonic() < deadline, "clicking robot_1 did not follow it"
        time.sleep(0.05)
    scale0 = browser.js("return window.fieldView.drawn.scale")
    under = browser.js("return window.fieldView.pixelToWorld(300, 200)")
    browser.js("const r = arguments[0].getBoundingClientRect(); arguments[0].dispatchEvent(new WheelEvent('wheel', "
               "{deltaY: -400, clientX: r.left + 300, clientY: r.top + 200, bubbles: true, cancelable: true}));",
               canvas)
    deadline = time.monotonic() + 10.0
    while browser.js("return window.fieldView.drawn.scale") == scale0:
        assert time.monotonic() < deadline, "the wheel did not zoom"
        time.sleep(0.05)
    assert browser.js("return window.fieldView.drawn.scale") == pytest.approx(scale0 * math.exp(0.6), rel=1e-9)
    assert browser.js("return window.fieldView.pixelToWorld(300, 200)") == pytest.approx(under, abs=1e-9)
    ActionChains(browser.driver).double_click(canvas).perform()
    deadline = time.monotonic() + 10.0
    while browser.js("return window.fieldView.drawn.scale") != pytest.approx(scale0, rel=1e-9):
        assert time.monotonic() < deadline, "double-click did not fit the field again"
        time.sleep(0.05)


def is_ball_orange(rgb) -> bool:
    r, g, b = rgb
    return r > 200 and 100 < g < 170 and b < 60


def test_the_page_draws_the_graphs_robots_ball_and_catch_point(graph_and_view):
    director, browser, view = graph_and_view
    scene = next(s for s in default_scenes(FIELD) if s.name.startswith("kick 3.0 m/s straight"))
    director.place_robot(KICKER, scene.kicker_pose)
    director.wait_sim(0.05)
    ball_xy = director.ball_at_kicker(scene.kicker_pose)
    director.place_ball(*ball_xy)
    director.wait_sim(0.05)
    director.place_robot(RECEIVER, scene.receiver_pose)
    director.wait_sim(1.0)

    # The ball at rest beside the kicker: drawn where the ground truth has it, by report and in pixels.
    drawn = wait_drawn(director, browser, lambda d: d["ball_world"] and math.dist(d["ball_world"], ball_xy) < 0.02,
                       20.0, "the ball at the kicker")
    catch_up(director, drawn["t"])
    t_ball, bx, by, *_ = truth_at(director.series.ball_truth, drawn["ball_t"])
    assert abs(t_ball - drawn["ball_t"]) < 1e-3
    assert math.dist(drawn["ball_world"], (bx, by)) < 0.003  # the page rounds to 0.1 mm
    assert drawn["robots"] == 2 and sorted(drawn["robot_ids"]) == [RECEIVER, KICKER]
    _, rx, ry, *_ = truth_at(director.series.robot_truth, drawn["t"])
    assert math.dist(drawn["robot_px"][str(RECEIVER)], canvas_pixel(browser, rx, ry)) < 2.0
    image = browser.screenshot()
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    image.save(ARTIFACTS / "field_view_ball_at_rest.png")
    px, py = canvas_pixel(browser, bx, by)
    assert is_ball_orange(image.getpixel((px, py))), f"no ball at {(px, py)}: {image.getpixel((px, py))}"
    # and the orange is the ball there, not the whole neighbourhood
    assert not any(is_ball_orange(image.getpixel((px + dx, py + dy))) for dx, dy in ((12, 0), (-12, 0), (0, 12)))
    before = {c["id"]: c["world"] for c in drawn["catch_points"]}
    check_follow_zoom_and_fit(browser, drawn)

    # Kick at robot_0: the path, robot_0's catch point near it and the receiver's target appear.
    n_events = len(director.events)
    director.kick.publish(Float64(data=scene.kick_speed_mps))
    assert director.spin_until(lambda: any("fired" in e for e in director.events[n_events:]), 10.0, "the kick")
    # the simulator's events, which the view takes by callback rather than once per frame, reach the page
    assert director.spin_until(lambda: "fired" in browser.js("return document.getElementById('events').textContent"),
                               10.0, "the kick on the page")

    def rolling_and_predicted(d):
        points = {c["id"]: c["world"] for c in d["catch_points"]}
        return (d["path"] is not None and RECEIVER in points and d["receiver"] is not None
                and math.dist(points[RECEIVER], scene.receiver_pose[:2]) < 0.35)

    drawn = wait_drawn(director, browser, rolling_and_predicted, 10.0, "a catch point for robot_0 after the kick")
    catch_up(director, drawn["t"])
    browser.screenshot().save(ARTIFACTS / "field_view_after_kick.png")
    assert RECEIVER not in before or math.dist(before[RECEIVER], scene.receiver_pose[:2]) > 1.0
    assert drawn["receiver"]["id"] == RECEIVER
    # the marks every 0.25 s that the page puts on the path: on it, in order, up to its stop (or the wall it
    # meets first, path["wall"]: the stop when it meets none)
    path = drawn["path"]
    assert len(path["marks"]) == min(40, int(path["wall_time"] / 0.25)) > 0
    along = [math.dist(path["start"], m) for m in path["marks"]]
    assert along == sorted(along) and along[-1] <= math.dist(path["start"], path["wall"]) + 1e-6
    for mark in path["marks"]:
        assert math.dist(mark, path["start"]) + math.dist(mark, path["wall"]) == pytest.approx(
            math.dist(path["start"], path["wall"]), abs=1e-6)
    # the path starts at the predictor's filtered ball of a recent frame, which the view takes from /ball/track
    # (with v_shoot, phase, uncertain and the ball seen) instead of /ball/state and four more topics
    states = [(x, y) for t, x, y, *_ in director.series.ball_state if drawn["t"] - 0.5 <= t <= drawn["t"] + 0.05]
    assert states and min(math.dist(path["start"], p) for p in states) < 2e-4  # the page's 0.1 mm
    node = director.node
    readers = {t.name: {i.node_name for i in node.get_subscriptions_info_by_topic(t.name)}
               for t in (c.BALL_TRACK, c.BALL_STATE, c.VISION_BALL, c.BALL_PHASE)}
    assert "field_view" in readers[c.BALL_TRACK.name]
    assert not any("field_view" in names for names in list(readers.values())[1:]), readers
    # the predictor's catch points of the last half second: the drawn one is among them
    recent = [(x, y) for t, x, y in director.series.catch_points if drawn["t"] - 0.5 <= t <= drawn["t"] + 0.05]
    drawn_point = next(c["world"] for c in drawn["catch_points"] if c["id"] == RECEIVER)
    assert recent and min(math.dist(drawn_point, p) for p in recent) < 0.01
    # the moving ball is drawn where the ground truth had it at the drawn frame's time
    t_ball, bx, by, *_ = truth_at(director.series.ball_truth, drawn["ball_t"])
    assert abs(t_ball - drawn["ball_t"]) < 1e-3 and math.dist(drawn["ball_world"], (bx, by)) < 0.003
    assert re.search(r"field view at", view.output())


def test_without_chromium_the_browser_tests_fail_under_ci_and_skip_elsewhere(monkeypatch):
    module = sys.modules[__name__]
    monkeypatch.setattr(module, "chromium_missing", lambda: ["/usr/bin/chromium"])
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="chromium missing"):
        require_chromium()
    monkeypatch.delenv("CI")
    with pytest.raises(pytest.skip.Exception):
        require_chromium()
