"""Recording (rosbag2 MCAP), replay, regression checks and Rerun export."""

__all__: list[str] = []
