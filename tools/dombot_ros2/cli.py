"""Command line: ``ros2 <command> <verb> ...`` with ros2cli's arguments and exit codes."""

from __future__ import annotations

import argparse
import glob
import os
import shutil
import sys
from pathlib import Path

HANDOVER_ENV = "DOMBOT_ROS2_REAL"  # tests point this at a stand-in 'real' ros2
SPIN_TIME = 0.5  # s of discovery before answering graph questions (then until it settles)
CALL_TIMEOUT = 30.0  # s to wait for a service or action server that is not there
PARAM_TIMEOUT = 10.0  # s for a node's parameter services to answer


def real_ros2() -> str | None:
    """A ros2cli installed on this machine, other than this launcher, if any."""
    if os.environ.get(HANDOVER_ENV):
        return os.environ[HANDOVER_ENV]
    me = Path(sys.argv[0]).resolve()
    candidates = [
        shutil.which("ros2", path=d) for d in os.environ.get("PATH", "").split(os.pathsep)
    ]
    candidates += sorted(glob.glob("/opt/ros/*/bin/ros2"))
    for candidate in candidates:
        if candidate and Path(candidate).resolve() != me and not _is_this_launcher(candidate):
            return candidate
    return None


def _is_this_launcher(path: str) -> bool:
    try:
        return "dombot_ros2" in Path(path).read_text(errors="ignore")[:2000]
    except OSError:
        return False


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ros2", description="ros2 is an extensible command-line tool for ROS 2."
    )
    commands = parser.add_subparsers(dest="command", metavar="Commands")
    commands.required = True

    run = commands.add_parser("run", help="Run a package specific executable")
    run.add_argument("--prefix", help="Prefix command, which should go before the executable")
    run.add_argument("package_name")
    run.add_argument("executable_name")
    run.add_argument(
        "argv", nargs=argparse.REMAINDER, help="Pass arbitrary arguments to the executable"
    )

    pkg = _verbs(commands, "pkg", "Various package related sub-commands")
    pkg.add_parser("list", help="Output a list of available packages")
    prefix = pkg.add_parser("prefix", help="Output the prefix path of a package")
    prefix.add_argument("package_name")
    prefix.add_argument("--share", action="store_true", help="Show share directory for the package")
    executables = pkg.add_parser(
        "executables", help="Output a list of package specific executables"
    )
    executables.add_argument("package_name", nargs="?")
    executables.add_argument("--full-path", action="store_true")

    topic = _verbs(commands, "topic", "Various topic related sub-commands")
    listing = topic.add_parser("list", help="Output a list of available topics")
    listing.add_argument("-t", "--show-types", action="store_true")
    listing.add_argument("--include-hidden-topics", action="store_true")
    for verb, text in (
        ("echo", "Output messages from a topic"),
        ("hz", "Print the average publishing rate"),
    ):
        sub = topic.add_parser(verb, help=text)
        sub.add_argument("topic_name")
        sub.add_argument("message_type", nargs="?")
        if verb == "echo":
            sub.add_argument(
                "--once", action="store_true", help="Print the first message received and then exit"
            )
        else:
            sub.add_argument("--window", "-w", type=int, default=10000)
    info = topic.add_parser("info", help="Print information about a topic")
    info.add_argument("topic_name")
    info.add_argument("-v", "--verbose", action="store_true")
    pub = topic.add_parser("pub", help="Publish a message to a topic")
    pub.add_argument("topic_name")
    pub.add_argument("message_type")
    pub.add_argument("values", nargs="?", default="{}")
    pub.add_argument("-r", "--rate", type=float, default=1.0)
    pub.add_argument("-1", "--once", action="store_true")
    pub.add_argument("-t", "--times", type=int, default=0)

    service = _verbs(commands, "service", "Various service related sub-commands")
    listing = service.add_parser("list", help="Output a list of available services")
    listing.add_argument("-t", "--show-types", action="store_true")
    listing.add_argument("--include-hidden-services", action="store_true")
    kind = service.add_parser("type", help="Output a service's type")
    kind.add_argument("service_name")
    call = service.add_parser("call", help="Call a service")
    call.add_argument("service_name")
    call.add_argument("service_type")
    call.add_argument("values", nargs="?", default="{}")
    call.add_argument(
        "--timeout",
        type=float,
        default=CALL_TIMEOUT,
        help="seconds to wait for the service and then for its response (%(default)s)",
    )

    param = _verbs(commands, "param", "Various param related sub-commands")
    listing = param.add_parser("list", help="Output a list of available parameters")
    listing.add_argument("node_name", nargs="?", help="Name of the ROS node")
    get = param.add_parser("get", help="Get parameter")
    get.add_argument("node_name", help="Name of the ROS node")
    get.add_argument("parameter_name", help="Name of the parameter")
    get.add_argument("--hide-type", action="store_true", help="Hide the type information")
    put = param.add_parser("set", help="Set parameter")
    put.add_argument("node_name", help="Name of the ROS node")
    put.add_argument("parameter_name", help="Name of the parameter")
    put.add_argument("value", help="Value of the parameter")

    action = _verbs(commands, "action", "Various action related sub-commands")
    listing = action.add_parser("list", help="Output a list of action names")
    listing.add_argument("-t", "--show-types", action="store_true")
    goal = action.add_parser("send_goal", help="Send an action goal")
    goal.add_argument("action_name", help="Name of the ROS action (e.g. '/fibonacci')")
    goal.add_argument("action_type", help="Type of the ROS action")
    goal.add_argument("goal", nargs="?", default="{}", help="Goal request values in YAML format")
    goal.add_argument(
        "-f", "--feedback", action="store_true", help="Echo feedback messages for the goal"
    )
    goal.add_argument(
        "--timeout",
        type=float,
        default=CALL_TIMEOUT,
        help="seconds to wait for the action server (%(default)s); the goal may run longer",
    )

    interface = _verbs(commands, "interface", "Show information about ROS interfaces")
    show = interface.add_parser("show", help="Output the interface definition")
    show.add_argument("type")
    show.add_argument("--all-comments", action="store_true")
    show.add_argument("--no-comments", action="store_true")
    interface.add_parser("list", help="List all interface types available")
    package = interface.add_parser(
        "package", help="Output a list of available interface types within one package"
    )
    package.add_argument("package_name")

    node = _verbs(commands, "node", "Various node related sub-commands")
    listing = node.add_parser("list", help="Output a list of available nodes")
    listing.add_argument(
        "-a", "--all", action="store_true", help="Display all nodes even hidden ones"
    )
    node_info = node.add_parser("info", help="Output information about a node")
    node_info.add_argument("node_name")
    return parser


def _verbs(commands, name: str, text: str):
    parser = commands.add_parser(name, help=text)
    verbs = parser.add_subparsers(dest="verb", metavar="Commands")
    verbs.required = True
    return verbs


def dispatch(args: argparse.Namespace) -> int:
    # Imported here so that 'ros2 --help' and the handover need no ROS libraries.
    from dombot_ros2 import graph, interfaces, packages

    if args.command == "run":
        return packages.run(args.package_name, args.executable_name, args.argv, args.prefix)
    if args.command == "pkg":
        return _print(_pkg(args, packages))
    if args.command == "interface":
        return _print(_interface(args, interfaces))
    from rclpy.executors import ExternalShutdownException

    # A call waits for its own server; listings and node look-ups wait for the graph.
    calls = args.verb in ("call", "send_goal")
    # What the arguments alone decide is checked before the graph is discovered, which
    # waits out the whole settle limit in an empty graph: a typo fails at once.
    message = _checked_before_discovery(args, graph)
    try:
        with graph.graph_node(SPIN_TIME, settle_limit=0.0 if calls else 10.0) as node:
            return _print(_graph(args, graph, node, message))
    except ExternalShutdownException:  # Ctrl-C or SIGTERM while spinning
        return 0


def _pkg(args, packages) -> list[str]:
    if args.verb == "list":
        return packages.list_packages()
    if args.verb == "prefix":
        return [packages.prefix(args.package_name, args.share)]
    return packages.executables(args.package_name, args.full_path)


def _interface(args, interfaces) -> list[str]:
    if args.verb == "show":
        return [interfaces.interface_text(args.type, args.all_comments, args.no_comments)]
    everything = interfaces.all_interfaces()
    if args.verb == "package":
        if args.package_name not in everything:
            raise interfaces.UnknownInterfaceError(f"Unknown package '{args.package_name}'")
        return [f"{args.package_name}/{name}" for name in everything[args.package_name]]
    lines = []
    for title, kind in (("Messages", "msg"), ("Services", "srv"), ("Actions", "action")):
        lines.append(f"{title}:")
        lines += [
            f"    {package}/{name}"
            for package, names in everything.items()
            for name in names
            if name.startswith(kind + "/")
        ]
    return lines


def _checked_before_discovery(args, graph):
    """Refuse a bad type or message now; return ``topic pub``'s message."""
    if args.command != "topic":
        return None
    if args.verb == "pub":
        return graph.message_from(args.message_type, args.values)
    if args.verb in ("echo", "hz") and args.message_type:
        graph.load_type(args.message_type, kind="msg")
    return None


def _graph(args, graph, node, message) -> list[str]:
    if args.command == "topic":
        if args.verb == "list":
            return graph.topic_list(node, args.show_types, args.include_hidden_topics)
        if args.verb == "echo":
            graph.topic_echo(node, args.topic_name, args.message_type, args.once, wait=5.0)
        elif args.verb == "hz":
            graph.topic_hz(node, args.topic_name, args.message_type, args.window, wait=5.0)
        elif args.verb == "info":
            return graph.topic_info(node, args.topic_name, args.verbose, wait=5.0)
        elif args.verb == "pub":
            times = 1 if args.once else args.times
            graph.topic_pub(node, args.topic_name, message, args.rate, times)
        return []
    if args.command == "service":
        if args.verb == "list":
            return graph.service_list(node, args.show_types, args.include_hidden_services)
        if args.verb == "type":
            return [graph.service_type(node, args.service_name)]
        graph.service_call(node, args.service_name, args.service_type, args.values, args.timeout)
        return []
    if args.command == "param":
        return _param(args, node)
    if args.command == "action":
        return _action(args, node)
    if args.verb == "list":
        return graph.node_list(node, args.all)
    return graph.node_info(node, args.node_name)


def _param(args, node) -> list[str]:
    from dombot_ros2 import params

    if args.verb == "list":
        return params.param_list(node, args.node_name, PARAM_TIMEOUT)
    if args.verb == "get":
        return [
            params.param_get(
                node, args.node_name, args.parameter_name, args.hide_type, PARAM_TIMEOUT
            )
        ]
    return [params.param_set(node, args.node_name, args.parameter_name, args.value, PARAM_TIMEOUT)]


def _action(args, node) -> list[str]:
    from dombot_ros2 import actions

    if args.verb == "list":
        return actions.action_list(node, args.show_types)
    actions.send_goal(
        node, args.action_name, args.action_type, args.goal, args.feedback, args.timeout
    )
    return []


def _print(lines: list[str]) -> int:
    for line in lines:
        print(line)
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    real = real_ros2()
    if real is not None:
        os.execv(real, [real, *argv])
    args = build_parser().parse_args(argv)
    try:
        return dispatch(args)
    except KeyboardInterrupt:
        return 0
    except BrokenPipeError:  # output piped into head & co., which stopped reading
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (LookupError, RuntimeError, ValueError) as error:
        print(error, file=sys.stderr)
        return 1
