"""rh5_bringup: RH5's hardware layer, the composed control process, simulated hardware, recording, reports and
the ``rh5`` command line, in layers that import only downwards (docs/architecture.md):

* ``hardware``: NDLCom codec, transports (UDP, CAN), the 1 kHz driver core and driver node; what a robot PC needs;
* ``control``: the control process, one read -> update -> write cycle over hardware, mapper and stabilizer;
* ``sim``: emulated boards, actuators and PyBullet physics, and the simulated-hardware node;
* ``recording``: rosbag2-compatible MCAP bags and the recorder node;
* ``analysis``: experiment reports from recorded bags;
* ``orchestration``: the bringup description, processes, sessions, experiments, the CLI and launch files.

tests/test_layers.py enforces the order; package.xml's conditional dependencies follow it.
"""

__all__ = ["analysis", "control", "hardware", "orchestration", "recording", "sim"]
