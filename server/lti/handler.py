"""What a verified launch opens. The course (server/course/, wired in server/main.py) gives the app a
`LaunchHandler`; until it does, `EchoHandler` answers a small page that says who launched where."""

from __future__ import annotations

from html import escape
from typing import Protocol

from server.core.answers import Answer
from server.lti.launch import Launch
from server.lti.pages import page


class LaunchHandler(Protocol):
    def launched(self, launch: Launch, base: str) -> Answer:
        """The answer to a verified launch (its page, or a redirect to it); `base` the server's URL as the request
        named it. Called in a thread (it may read and write the database)."""
        ...


class EchoHandler:
    """The default handler: "launched as <role> in <context title>", and what the launch offers."""

    def launched(self, launch: Launch, base: str) -> Answer:
        role = launch.course_role or "no course role"
        where = (launch.context or {}).get("title") or (launch.context or {}).get("id") or "no course"
        services = [name for name, there in (("grades", launch.ags), ("members", launch.nrps)) if there]
        body = (
            f'<h1 data-role="{escape(role, quote=True)}">launched as {escape(role)} in {escape(where)}</h1>\n'
            f"<p>{escape(launch.message_type)} from {escape(launch.platform.get('name') or launch.platform['issuer'])}"
            f"{'; services: ' + ', '.join(services) if services else ''}.</p>"
        )
        return page("Launched", body)
