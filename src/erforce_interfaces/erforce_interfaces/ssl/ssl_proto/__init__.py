"""The SSL protocols' wire formats: our own ``.proto`` definitions and the Python modules protoc
generates from them.

The definitions are written from the league's documented message and field names and numbers (the
interface); they are not copies of the league's files. Every message lives in the proto package
``erforce.ssl`` so that a process may also load the league's own generated modules without a
descriptor-pool clash. ``python -m erforce_interfaces.ssl.ssl_proto.generate`` regenerates the
``*_pb2.py`` modules beside the ``.proto`` files; a test fails when they are out of date.
"""
