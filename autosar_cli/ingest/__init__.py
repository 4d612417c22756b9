"""Log readers and decoders. Importing the package registers every reader's containers with
:func:`.sources.register_container` (a new container: its module calls that, and is imported here)."""

from . import mcap_source, rosbag_source  # noqa: F401  (register the mcap, ros1 and rosbag2 containers)
