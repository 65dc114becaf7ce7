"""``python -m cwproc`` runs the command line."""

from cwproc.cli import main

main()
