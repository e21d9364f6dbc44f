"""The team tick: the field node that runs the paper's timestep on a real team.

``core`` holds the pure state machine (snapshot, decide, act, settle), ``node`` the ROS node
that runs it against the localiser, the mapper, the controllers, the drive executors and the
blade drivers. ``docs/field.md`` describes a tick; ``docs/architecture.md`` places the node.
"""
