"""Generated bindings of the ``findme.v1`` bus messages (``*_pb2.py`` / ``*_pb2.pyi``).

Do not edit the generated files: change the ``.proto`` files next to them and run
``python tools/gen_schemas.py``. Use the ``schemas`` package for encoding and decoding.
"""
