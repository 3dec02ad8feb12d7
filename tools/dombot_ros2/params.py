"""``ros2 param list|get|set`` through a node's standard parameter services, with
ros2param's output (rclpy's AsyncParameterClient does the calls)."""

from __future__ import annotations

import rclpy
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rclpy.node import Node
from rclpy.parameter import get_parameter_value
from rclpy.parameter_client import AsyncParameterClient

from dombot_ros2.graph import await_node, node_list
from dombot_ros2.packages import CommandError

# ParameterType → (ros2param's label, the ParameterValue field holding the value)
VALUE_LABELS = {
    ParameterType.PARAMETER_BOOL: ("Boolean value is:", "bool_value"),
    ParameterType.PARAMETER_INTEGER: ("Integer value is:", "integer_value"),
    ParameterType.PARAMETER_DOUBLE: ("Double value is:", "double_value"),
    ParameterType.PARAMETER_STRING: ("String value is:", "string_value"),
    ParameterType.PARAMETER_BYTE_ARRAY: ("Byte values are:", "byte_array_value"),
    ParameterType.PARAMETER_BOOL_ARRAY: ("Boolean values are:", "bool_array_value"),
    ParameterType.PARAMETER_INTEGER_ARRAY: ("Integer values are:", "integer_array_value"),
    ParameterType.PARAMETER_DOUBLE_ARRAY: ("Double values are:", "double_array_value"),
    ParameterType.PARAMETER_STRING_ARRAY: ("String values are:", "string_array_value"),
}


def absolute(node_name: str) -> str:
    return node_name if node_name.startswith("/") else f"/{node_name}"


def _client(node: Node, node_name: str, timeout: float) -> AsyncParameterClient:
    if not await_node(node, absolute(node_name), timeout):
        raise CommandError("Node not found")
    client = AsyncParameterClient(node, absolute(node_name))
    if not client.wait_for_services(timeout_sec=timeout):
        raise CommandError(
            f"the parameter services of '{absolute(node_name)}' did not answer in {timeout:g} s"
        )
    return client


def _result(node: Node, future, what: str, timeout: float):
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    if not future.done() or future.result() is None:
        raise CommandError(f"no response to {what} within {timeout:g} s")
    return future.result()


def param_list(node: Node, node_name: str | None, timeout: float) -> list[str]:
    """Each node's parameter names, indented; a 'node:' header only when listing all."""
    names = (
        [absolute(node_name)]
        if node_name
        else [
            name
            for name in node_list(node, include_hidden=False)
            if f"{name}/list_parameters" in dict(node.get_service_names_and_types())
        ]
    )
    lines = []
    for name in names:
        client = _client(node, name, timeout)
        response = _result(node, client.list_parameters(), f"{name}/list_parameters", timeout)
        lines += [] if node_name else [f"{name}:"]
        lines += [f"  {parameter}" for parameter in sorted(response.result.names)]
    return lines


def param_get(node: Node, node_name: str, parameter: str, hide_type: bool, timeout: float) -> str:
    client = _client(node, node_name, timeout)
    response = _result(node, client.get_parameters([parameter]), "get_parameters", timeout)
    if not response.values or response.values[0].type == ParameterType.PARAMETER_NOT_SET:
        raise CommandError("Parameter not set")
    value: ParameterValue = response.values[0]
    label, field = VALUE_LABELS[value.type]
    shown = getattr(value, field)
    return str(shown) if hide_type else f"{label} {shown}"


def param_set(node: Node, node_name: str, parameter: str, text: str, timeout: float) -> str:
    """Set one parameter from its YAML text as ros2param does; a refusal is an error."""
    client = _client(node, node_name, timeout)
    message = Parameter(name=parameter, value=get_parameter_value(string_value=text))
    response = _result(node, client.set_parameters([message]), "set_parameters", timeout)
    result = response.results[0]
    if not result.successful:
        raise CommandError(
            "Setting parameter failed" + (f": {result.reason}" if result.reason else "")
        )
    return "Set parameter successful" + (f": {result.reason}" if result.reason else "")
