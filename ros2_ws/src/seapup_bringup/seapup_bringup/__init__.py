"""Seapup bringup: graphs of nodes, the demo, the ./seapup command registry and benchmarks.

The top of the dependency graph (msgs <- common <- sim, control, ident <-
bringup): the only package that may start the simulator and the controllers
together.
"""
