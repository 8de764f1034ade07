"""The command-line parser: every sub-command is there without going through ``main``."""
from symtorch.cli import build_parser


def test_build_parser_alone_has_every_subcommand():
    p = build_parser()  # as documentation generators and shell completion call it
    assert p.parse_args(["detect", "m.off", "--mode", "group"]).mode == "group"
    assert p.parse_args(["info", "--demo"]).command == "info"
    assert p.parse_args(["precompute", "src", "out", "--k", "40"]).k == 40
    assert p.parse_args(["show", "m.off", "--out", "m.png"]).out == "m.png"
