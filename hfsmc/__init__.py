"""hfsmc: a compiler for hierarchical finite state machines that program robot behaviours."""

__version__ = "0.1.0"
