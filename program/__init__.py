"""The programming layer: programs of behaviour calls, ROS services and block pages."""
