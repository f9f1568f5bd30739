"""What each command does, end to end, as Python functions with keyword-only options.

The command line (`biostudy.cli`) parses arguments and calls these; the
Python API (`biostudy`) calls the same functions.  Each loads and validates
its inputs (bad input: `BadInput`), runs what it must through
`biostudy.execution`, measures through `biostudy.reports` and writes through
`biostudy.data` and `biostudy.plots`.
"""
