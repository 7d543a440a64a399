"""The SSL nodes' schema files state the protocols' well-known addresses as defaults; the codecs own
them (ssl_vision, ssl_sim). These checks keep the two in step."""

from erforce_interfaces import ssl_sim, ssl_vision
from erforce_interfaces.param_schema import load_schema


def test_the_schema_defaults_are_the_protocols_addresses():
    bridge = load_schema("erforce_ball_model", "ssl_vision_bridge").defaults()
    assert (bridge["group"], bridge["port"]) == (ssl_vision.SSL_VISION_GROUP, ssl_vision.SSL_VISION_PORT) \
        == ("224.5.23.2", 10006)
    plant = load_schema("erforce_sim", "plant").defaults()
    assert (plant["ssl_vision_group"], plant["ssl_vision_port"]) == (
        ssl_vision.SSL_VISION_GROUP, ssl_vision.SSL_SIMULATOR_VISION_PORT) == ("224.5.23.2", 10020)
    assert plant["vision_output"] == "ros"
    sim_bridge = load_schema("erforce_interfaces", "ssl_sim_bridge").defaults()
    server = load_schema("erforce_sim", "ssl_sim_server").defaults()
    assert sim_bridge["control_port"] == server["control_port"] == ssl_sim.SIM_CONTROL_PORT == 10300
    # 0 stands for the team's default port of the protocol (ROBOT_CONTROL_PORTS, GRSIM_STATUS_PORTS)
    assert sim_bridge["command_port"] == sim_bridge["grsim_status_port"] == server["robot_control_port"] == 0
