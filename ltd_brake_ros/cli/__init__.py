"""``ltd-brake``: the command line, one module per verb."""
