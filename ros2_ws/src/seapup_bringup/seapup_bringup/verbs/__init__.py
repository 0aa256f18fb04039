"""The ``./seapup`` verbs: each module parses its arguments, calls the product (the run layer, the graph harness
and runners, the report) and prints or writes what it got. :mod:`seapup_bringup.cli` registers them; no other
product module imports a verb."""
