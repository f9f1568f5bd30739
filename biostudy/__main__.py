"""`python -m biostudy ...` is the same as the `biostudy` command."""
from .cli import app

app(prog_name="biostudy")
