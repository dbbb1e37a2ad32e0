"""Demonstrations: the :class:`~.trajectories.Trajectories` type and its checks
(:mod:`.trajectories`), a simulated person (:mod:`.simulation`), CSV I/O (:mod:`.csv_io`,
on the row reader and number parsers of :mod:`.csv_rows`), Cartesian recordings turned
into demonstrations (:mod:`.recordings`; a ROS bag's positions as a recording, :mod:`.rosbag`), and
the ``imitation`` library's trajectories and MCE IRL environment (:mod:`.imitation_io`)."""

#: The package defines no names of its own: import them from its modules.
__all__: list[str] = []
