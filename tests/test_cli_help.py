"""Every command and every option of the CLI explains itself in --help."""

import click

from flightrecon.cli.main import cli


def _commands(cmd, path):
    yield path, cmd
    if isinstance(cmd, click.Group):
        for name, sub in cmd.commands.items():
            yield from _commands(sub, [*path, name])


def test_every_option_has_help_text():
    missing = [f"{' '.join(path)} {'/'.join(p.opts)}"
               for path, cmd in _commands(cli, ["flightrecon"]) for p in cmd.params
               if isinstance(p, click.Option) and not (p.help or "").strip()]
    assert missing == []


def test_every_command_has_a_description():
    assert [" ".join(path) for path, cmd in _commands(cli, ["flightrecon"])
            if not (cmd.help or "").strip()] == []


def test_the_main_commands_are_registered():
    assert {"info", "clean", "simulate", "reconstruct", "plot", "export", "coeffs",
            "batch"} <= set(cli.commands)
