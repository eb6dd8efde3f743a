"""Options that users put in more than one place, accepted in each.

* The global options (``--port``, ``--baud``, ``--echo``, ``--timeout-margin-ms``,
  ``--retries``, ``--robot``, ``-v``) are accepted after the subcommand too: ``busarm arm
  pose --port twin`` is ``busarm --port twin arm pose``. Each command gets hidden copies of them
  (except where it has an option of the same name, such as ``sim serve --echo``).
* The arm options (``--config``, ``--calibration``) are accepted before the command
  (``busarm --config X arm pose``), at the group (``busarm arm --config X pose``) and
  after the command (``busarm arm pose --config X``), for every command that takes them;
  a command that takes none says so.

Precedence: the option nearest the command wins; then one before the command; then the
environment (``BUSARM_PORT``, ``BUSARM_ARM``, ``BUSARM_CALIBRATION``); then the default.
An option that is still unknown where it was given gets a hint naming the commands that
take it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import click
from click.core import ParameterSource

from busarm.cli.common import ArmContext, Settings, metavar_from_help

__all__ = [
    "ARM_ENVVAR",
    "ARM_NAMES",
    "GLOBAL_NAMES",
    "Callback",
    "accept_everywhere",
    "explain",
    "log_verbosely",
    "name_numbers",
    "walk",
]


GLOBAL_NAMES = ("port", "baudrate", "echo", "timeout_margin_ms", "retries", "robot_file",
                "verbose")
"""The root options that commands accept after themselves too."""
ARM_NAMES = ("config", "calibration")
ARM_ENVVAR = "BUSARM_ARM"
"""The environment's arm description, for every --config."""
_ROOT_ARM = "busarm.arm_options"
"""ctx.meta key of the arm options given before the command."""
_GLOBAL_PREFIX = "_global_"
_ARM_PREFIX = "_arm_"
_UNUSED_PREFIX = "_unused_"

Callback = Callable[[click.Context, click.Parameter, Any], Any]


def log_verbosely() -> None:
    """What ``-v`` does: log bus details (echo detection) to stderr."""
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")


def walk(group: click.Group, path: tuple[str, ...] = ()) -> Iterator[
        tuple[tuple[str, ...], click.Command]]:
    """Every command under ``group`` (groups too), with its path of names."""
    for name, command in group.commands.items():
        yield (*path, name), command
        if isinstance(command, click.Group):
            yield from walk(command, (*path, name))


def name_numbers(group: click.Group) -> None:
    """Give every number option without a metavar one word instead of click's ``INTEGER
    RANGE``, which reads as two arguments: ``N`` for whole numbers, else its unit as its
    help says it (``MS``, ``MM_S``; ``busarm.cli.help_style``)."""
    for command in (group, *(c for _, c in walk(group))):
        for param in command.params:
            if isinstance(param, click.Option) and param.metavar is None:
                if isinstance(param.type, click.types.IntParamType):
                    param.metavar = "N"
                elif isinstance(param.type, click.types.FloatParamType):
                    param.metavar = metavar_from_help(param.help or "")


def _taken(command: click.Command) -> set[str]:
    return {o for p in command.params for o in (*p.opts, *p.secondary_opts)}


def _copy(param: click.Parameter, name: str, callback: Callback) -> click.Option:
    """A hidden option with ``param``'s names and type, reported to ``callback`` only."""
    assert isinstance(param, click.Option)
    return click.Option([*param.opts, name], type=None if param.is_flag else param.type,
                        is_flag=param.is_flag, hidden=True, expose_value=False,
                        callback=callback)


def _given(ctx: click.Context, param: click.Parameter) -> bool:
    return param.name is not None and \
        ctx.get_parameter_source(param.name) is ParameterSource.COMMANDLINE


def _apply_global(ctx: click.Context, param: click.Parameter, value: Any) -> None:
    settings = ctx.find_object(Settings)
    if settings is None or not _given(ctx, param) or param.name is None:
        return
    name = param.name.removeprefix(_GLOBAL_PREFIX)
    if name == "verbose":
        if value:
            log_verbosely()
        return
    setattr(settings, name, value)
    if name == "port":  # given after the command: this one, not $BUSARM_PORT
        settings.port_given, settings.port_from_env = True, False


def _apply_arm(ctx: click.Context, param: click.Parameter, value: Any) -> None:
    arm = ctx.find_object(ArmContext)
    if arm is not None and param.name is not None and _given(ctx, param):
        arm.override(**{param.name.removeprefix(_ARM_PREFIX): value})


def _before_beats_environment(name: str, callback: Callback | None) -> Callback:
    """A command's own --config/--calibration callback, for which one given before the
    command beats the environment (BUSARM_ARM), as the command line does."""
    def process(ctx: click.Context, param: click.Parameter, value: Any) -> Any:
        if param.name is not None and \
                ctx.get_parameter_source(param.name) is ParameterSource.ENVIRONMENT:
            value = ctx.find_root().meta.get(_ROOT_ARM, {}).get(name, value)
        return value if callback is None else callback(ctx, param, value)
    return process


def _refuse_arm(ctx: click.Context, param: click.Parameter, value: Any) -> None:
    """An arm option for a command that takes none: an error, not silently ignored."""
    if param.name is None:
        return
    name = param.name.removeprefix(_UNUSED_PREFIX)
    if not _given(ctx, param):
        value = ctx.find_root().meta.get(_ROOT_ARM, {}).get(name)
    if value is not None:
        raise click.UsageError(f"`{ctx.command_path}` takes no --{name} (given {value!r})", ctx)


def _remember_arm_option(ctx: click.Context, param: click.Parameter, value: Any) -> None:
    """``busarm --config X ...``: the default of every command's --config (and so on)."""
    if value is None or param.name is None:
        return
    ctx.meta.setdefault(_ROOT_ARM, {})[param.name] = value
    assert isinstance(ctx.command, click.Group)
    defaults: dict[str, Any] = dict(ctx.default_map or {})
    option = f"--{param.name}"
    for path, command in walk(ctx.command):
        for own in command.params:  # by option, not by name (`move --config` is config_name)
            if own.name is not None and option in own.opts and not getattr(own, "hidden", False):
                node = defaults
                for name in path:
                    node = node.setdefault(name, {})
                node[own.name] = value
    ctx.default_map = defaults


def _arm_group_options(root: click.Group) -> dict[str, click.Parameter]:
    """The --config and --calibration of the arm groups (arm, actions, camera)."""
    for _path, command in walk(root):
        params = {p.name: p for p in command.params if p.name in ARM_NAMES}
        if isinstance(command, click.Group) and set(params) == set(ARM_NAMES):
            return {name: p for name, p in params.items() if name is not None}
    return {}


def accept_everywhere(root: click.Group) -> None:
    """Give every command under ``root`` the global options, every command of an arm
    group the arm options, and ``root`` the arm options (call once, after every command
    is added)."""
    globals_ = [p for p in root.params if p.name in GLOBAL_NAMES]
    arm_options = _arm_group_options(root)
    for _path, command in walk(root):
        for param in globals_:
            if not _taken(command) & {*param.opts, *param.secondary_opts}:
                command.params.append(_copy(param, f"{_GLOBAL_PREFIX}{param.name}",
                                            _apply_global))
        if isinstance(command, click.Group) and "config" in {p.name for p in command.params}:
            for _sub_path, sub in walk(command):
                for name, param in arm_options.items():
                    if not _taken(sub) & set(param.opts):
                        sub.params.append(_copy(param, f"{_ARM_PREFIX}{name}", _apply_arm))
        for own in command.params:
            if "--config" in own.opts and isinstance(own, click.Option) and not own.hidden \
                    and not own.envvar:  # every arm description honours it, and says so
                own.envvar, own.show_envvar = ARM_ENVVAR, True
            for name in ARM_NAMES:
                if f"--{name}" in own.opts and getattr(own, "envvar", None):
                    own.callback = _before_beats_environment(name, own.callback)
        if not isinstance(command, click.Group):  # one that takes none says so, not ignores
            for name, param in arm_options.items():
                if not _taken(command) & set(param.opts):
                    command.params.append(_copy(param, f"{_UNUSED_PREFIX}{name}", _refuse_arm))
    for param in arm_options.values():
        assert isinstance(param, click.Option)
        root.params.append(click.Option(
            param.opts, type=param.type, expose_value=False, callback=_remember_arm_option,
            help=f"Same as the {param.opts[0]} of the commands that take one."))


def explain(exc: click.ClickException, root: click.Group, argv: Sequence[str]) -> str:
    """``exc``'s message; for an unknown option that other commands take, where it goes
    (``argv``: the command line, to name the command the user typed)."""
    message = exc.format_message()
    if not isinstance(exc, click.NoSuchOption) or exc.ctx is None or \
            not isinstance(exc.ctx.command, click.Group):
        return message  # an option unknown to a command: its --help says what it takes
    name = exc.option_name
    owners = [" ".join(path) for path, command in walk(root)
              if name in _taken(command) and not _hidden(command, name)]
    typed = _typed_command(root, argv)
    if typed in owners:
        return (f"{name} is an option of `busarm {typed}`, not of `{exc.ctx.command_path}`: "
                f"put it after the command (busarm {typed} {name} ...)")
    if not owners:
        return message
    shown = ", ".join(f"`busarm {o}`" for o in owners[:4]) + (", ..." if len(owners) > 4 else "")
    return f"no such option for `{exc.ctx.command_path}`: {name} is an option of {shown}"


def _typed_command(root: click.Group, argv: Sequence[str]) -> str | None:
    """The command named on ``argv`` (``arm pose``), or None."""
    path: list[str] = []
    group: click.Command = root
    for word in argv:
        if not isinstance(group, click.Group):
            break
        if word in group.commands:
            path.append(word)
            group = group.commands[word]
    return " ".join(path) or None


def _hidden(command: click.Command, option: str) -> bool:
    return any(option in p.opts and getattr(p, "hidden", False) for p in command.params)
