"""The field view: what is on the field as a browser page and for Foxglove. ``field_view`` is the core
(the world's state from the topics, frames as JSON), ``bag_replay`` a recorded bag as frames,
``field_view_node`` the node, ``view_server`` its HTTP/WebSocket server, ``foxglove_bridge`` the Foxglove
server, ``headless_browser`` a browser for the page's tests.

An observer: it subscribes and never commands. The demo and tests start it; no other module imports it.
"""
