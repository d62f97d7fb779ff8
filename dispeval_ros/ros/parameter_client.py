"""Another node's parameters through its standard services: read, set (checked), restore.

``dispeval tune --node NAME`` sets each configuration on a running stereo node with the
standard ``set_parameters_atomically`` service (``SetParameters`` would apply them one by one,
so a refused value could leave half a configuration set) and checks it took with
``GetParameters`` (a node may accept a value and clamp it); the values it found are put back at
the end. Every failure is one
:class:`~dispeval_ros.errors.ConfigurationError` line naming the node and the parameter.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters, SetParametersAtomically
from rclpy.parameter import Parameter, parameter_value_to_python

from dispeval_ros.errors import ConfigurationError

Value = bool | int | float | str
SERVICE_TIMEOUT = 5.0
"""Seconds to wait for a node's parameter services to appear, and for each answer."""


class RemoteParameters:
    """The parameters of the node ``target`` (a fully qualified name, e.g. ``/disparity_node``).

    ``node`` makes the service clients; ``executor`` spins while waiting for answers (the one
    ``node`` is added to).
    """

    def __init__(
        self, node: Any, target: str, executor: Any, timeout: float = SERVICE_TIMEOUT
    ) -> None:
        self.target = target if target.startswith("/") else f"/{target}"
        self._executor = executor
        self._timeout = timeout
        self._get = node.create_client(GetParameters, f"{self.target}/get_parameters")
        self._set = node.create_client(
            SetParametersAtomically, f"{self.target}/set_parameters_atomically"
        )
        self._original: dict[str, Value] = {}

    def wait(self) -> None:
        """Until the node's services answer; one line if it does not exist (or is not up)."""
        for client in (self._get, self._set):
            if not client.wait_for_service(timeout_sec=self._timeout):
                raise ConfigurationError(
                    f"no node {self.target}: its {client.srv_name} service did not appear "
                    f"within {self._timeout:g} s"
                )

    def get(self, names: Iterable[str]) -> dict[str, Value]:
        """The current values; one line naming a parameter the node does not have."""
        wanted = list(names)
        answer = self._call(self._get, GetParameters.Request(names=wanted), "read")
        if len(answer.values) != len(wanted):  # rclpy answers nothing if one is undeclared
            missing = next((name for name in wanted if not self._has(name)), wanted[0])
            raise ConfigurationError(f"node {self.target} has no parameter {missing!r}")
        values: dict[str, Value] = {}
        for name, value in zip(wanted, answer.values, strict=True):
            if value.type == ParameterType.PARAMETER_NOT_SET:
                raise ConfigurationError(f"node {self.target} has no parameter {name!r}")
            values[name] = parameter_value_to_python(value)
        return values

    def set(self, values: Mapping[str, Value]) -> None:
        """Set the values (all or none) and check each took.

        The values found before the first change of each are kept for :meth:`restore`. One
        line for a refusal (with the node's reason) or a value the node changed.
        """
        missing = [name for name in values if name not in self._original]
        if missing:
            self._original.update(self.get(missing))
        request = SetParametersAtomically.Request(
            parameters=[
                Parameter(name, value=value).to_parameter_msg() for name, value in values.items()
            ]
        )
        result = self._call(self._set, request, "set").result
        if not result.successful:
            given = ", ".join(f"{name} = {value!r}" for name, value in values.items())
            reason = f": {result.reason}" if result.reason else ""
            raise ConfigurationError(f"node {self.target} refused {given}{reason}")
        taken = self.get(values)
        for name, value in values.items():
            if taken[name] != value:
                raise ConfigurationError(
                    f"node {self.target} took {name} = {value!r} as {taken[name]!r}"
                )

    def restore(self) -> None:
        """Put back the values found before the first :meth:`set` (nothing if none was set)."""
        if self._original:
            original, self._original = self._original, {}
            self.set(original)
            self._original = {}

    def _has(self, name: str) -> bool:
        answer = self._call(self._get, GetParameters.Request(names=[name]), "read")
        return bool(answer.values) and answer.values[0].type != ParameterType.PARAMETER_NOT_SET

    def _call(self, client: Any, request: Any, what: str) -> Any:
        future = client.call_async(request)
        self._executor.spin_until_future_complete(future, timeout_sec=self._timeout)
        if not future.done():
            client.remove_pending_request(future)
            raise ConfigurationError(
                f"node {self.target} did not answer the {what} parameters request within "
                f"{self._timeout:g} s"
            )
        return future.result()
