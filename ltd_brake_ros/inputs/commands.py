"""The driver's and train control's inputs: the one table of their accepted ranges."""

#: Accepted range of each numeric command, inclusive: service brake demand as a fraction of the
#: emergency block force [-], traction (positive) or dynamic-brake (negative) demand as a
#: fraction of the powered vehicles' available effort [-].
COMMAND_RANGES = {"brake_demand": (0.0, 1.0), "traction": (-1.0, 1.0)}
