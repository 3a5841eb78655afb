"""ROS 2 messages for the ``ros2`` interface (docs/ros2.md): their definitions
(``definitions``) and the Python message packages generated from them
(``python_messages``)."""
