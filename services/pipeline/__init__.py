"""The pipeline services, one handler each: capture -> hypotheses -> selection ->
measurement (scenes, the measure queryable) and odometry (motion, poses, trajectory)."""
