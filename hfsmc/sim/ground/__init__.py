"""The simulated ground robot of ``hfsmc sim --robot diffdrive`` (docs/worlds.md, "Ground robots").

``world.py`` reads a world of walls and boxes, ``geometry.py`` measures it (laser rays,
contacts), ``base.py`` moves a differential-drive base in it, ``truth.py`` keeps what
really happened (poses, collisions, coverage). The ROS 2 side (topics, ``/clock``) is
``node.py``; nothing here knows about DDS.
"""
