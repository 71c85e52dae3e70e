"""Phalanx from Python: the client bindings (the servo-loop API, docs/sdk.md) and the record reader
(docs/records.md) share this package.

Client bindings: ``phalanx.Client(socket, deadline_ms=20, fallback="safe")``; states are ``phalanx.State`` with
numpy arrays (``pen_centre``, ``pen_force``, ``glove_fingertip``, ``sea_flexion``, ...). The extension module
``phalanx._phalanx`` is built by the project's CMake into this directory (docs/sdk.md "Python").
"""

try:
    from ._phalanx import VERSION, Client, Error, State  # noqa: F401
    try:  # libphalanx's network part, when built with Cyclone DDS (docs/sdk.md "Devices on the network")
        from ._phalanx import RemoteDevice, network_devices  # noqa: F401
    except ImportError:
        pass
except ImportError as _e:  # the extension is not built: the rest of the package still imports
    _client_import_error = _e

    def __getattr__(name):
        if name in ("VERSION", "Client", "Error", "State"):
            raise ImportError(
                "phalanx." + name + ": the client extension phalanx._phalanx is not built "
                "(cmake --build --preset host, with pybind11-dev installed): " + str(_client_import_error))
        raise AttributeError(name)
