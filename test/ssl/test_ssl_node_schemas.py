"""The protocols' well-known addresses: the codecs own them (ssl_vision, ssl_sim) with the numbers the
league documents, and the SSL nodes' schema files take them from there (``default_from``)."""

import re
from pathlib import Path

from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.ssl import ssl_log_replay, ssl_sim, ssl_vision

SRC = Path(__file__).resolve().parents[2] / "src"


def test_the_codecs_carry_the_documented_ports():
    assert (ssl_vision.SSL_VISION_GROUP, ssl_vision.SSL_VISION_PORT) == ("224.5.23.2", 10006)
    assert ssl_vision.SSL_SIMULATOR_VISION_PORT == 10020
    assert ssl_sim.SIM_CONTROL_PORT == 10300 and ssl_sim.ROBOT_CONTROL_PORTS == {"blue": 10301, "yellow": 10302}
    assert ssl_log_replay.VISION_GROUP == ("224.5.23.2", 10006)


def test_the_schema_defaults_are_the_protocols_addresses():
    bridge = load_schema("erforce_ball_model", "ssl_vision_bridge").defaults()
    assert (bridge["group"], bridge["port"]) == ("224.5.23.2", 10006)
    plant = load_schema("erforce_sim", "plant").defaults()
    assert (plant["ssl_vision_group"], plant["ssl_vision_port"]) == ("224.5.23.2", 10020)
    assert plant["vision_output"] == "ros"
    sim_bridge = load_schema("erforce_sim", "ssl_sim_bridge").defaults()
    server = load_schema("erforce_sim", "ssl_sim_server").defaults()
    assert sim_bridge["control_port"] == server["control_port"] == 10300
    # 0 stands for the team's default port of the protocol (ROBOT_CONTROL_PORTS, GRSIM_STATUS_PORTS)
    assert sim_bridge["command_port"] == sim_bridge["grsim_status_port"] == server["robot_control_port"] == 0


def test_no_schema_file_repeats_a_protocol_port_as_its_own_default():
    ports = {ssl_vision.SSL_VISION_PORT, ssl_vision.SSL_SIMULATOR_VISION_PORT, ssl_sim.SIM_CONTROL_PORT,
             *ssl_sim.ROBOT_CONTROL_PORTS.values(), ssl_sim.GRSIM_COMMAND_PORT}
    for path in SRC.glob("*/*/params/*.yaml"):
        text = path.read_text()
        literal = [int(v) for v in re.findall(r"default_value:\s*(\d+)\s*$", text, re.MULTILINE)]
        assert not ports & set(literal), f"{path.name}: use default_from for {sorted(ports & set(literal))}"
        assert ssl_vision.SSL_VISION_GROUP not in re.findall(r'default_value:\s*"?([\d.]+)"?', text), path.name
