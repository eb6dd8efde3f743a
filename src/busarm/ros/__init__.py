"""ROS 2 interop over Zenoh without ROS: rmw_zenoh's wire format, CDR via rosbags, the bridge."""

__all__: list[str] = []
