"""The former name of `biostudy.bundled`, kept while code written against it is updated."""
from .bundled import Entry, entries, resolve, studies_dir  # noqa: F401
