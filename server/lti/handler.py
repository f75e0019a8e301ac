"""What a verified launch opens. The course (server/course/, wired in server/main.py) gives the app a
`LaunchHandler`; until it does, `EchoHandler` answers a small page that says who launched where."""

from __future__ import annotations

from html import escape
from typing import Protocol

from starlette.requests import Request
from starlette.responses import Response

from server.lti.launch import Launch
from server.lti.pages import page


class LaunchHandler(Protocol):
    async def launched(self, launch: Launch, request: Request) -> Response:
        """The answer to a verified launch (its page, or a redirect to it)."""
        ...


class EchoHandler:
    """The default handler: "launched as <role> in <context title>", and what the launch offers."""

    async def launched(self, launch: Launch, request: Request) -> Response:
        role = launch.course_role or "no course role"
        where = (launch.context or {}).get("title") or (launch.context or {}).get("id") or "no course"
        services = [name for name, there in (("grades", launch.ags), ("members", launch.nrps)) if there]
        body = (
            f'<h1 data-role="{escape(role, quote=True)}">launched as {escape(role)} in {escape(where)}</h1>\n'
            f"<p>{escape(launch.message_type)} from {escape(launch.platform.get('name') or launch.platform['issuer'])}"
            f"{'; services: ' + ', '.join(services) if services else ''}.</p>"
        )
        return page("Launched", body)
