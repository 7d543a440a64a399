"""The SSL protocols' wire formats: our own ``.proto`` definitions and the Python modules protoc
generates from them.

The definitions are written from the league's documented message and field names and numbers (the
interface); they are not copies of the league's files. Every message lives in the proto package
``erforce.ssl`` so that a process may also load the league's own generated modules without a
descriptor-pool clash. The ``*_pb2.py`` modules are built, not committed: ``./run setup`` and the package's
build generate them (generate.py); a test fails when those beside the ``.proto`` files are out of date.
"""
