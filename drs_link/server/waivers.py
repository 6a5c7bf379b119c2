"""The waivers service: a console's ``w``, held by the server for the account that waived, audited once.

A ``drs capsule arm --waive`` grants its waivers for that one request, as one ``drs`` process did; a
console waives once and ARMs and FIREs with what it holds (``held_waivers``). Why held here and not on the
account's desk (``drs_link.ops.OperatorOps``): a command of the same account replaces the desk's waivers with its own
on each request, and would have dropped the console's. A reset of the capsule voids every account's.
"""

from __future__ import annotations

import threading

from drs_link.errors import ConfigError
from drs_link.ops import Waiver, WaiverBook
from drs_link.server.desks import Desks
from drs_link.server.peers import Peer


class WaiverService:
    def __init__(self, desks: Desks) -> None:
        self.desks = desks
        self._books: dict[tuple[int, str], WaiverBook] = {}
        self._lock = threading.Lock()

    def _book(self, peer: Peer, name: str) -> WaiverBook:
        capsule = self.desks.desk(peer).state.config.capsule(name).name  # an unknown capsule is refused first
        with self._lock:
            key = (peer.uid, capsule)
            if key not in self._books:
                self._books[key] = WaiverBook(self.desks.store, capsule, self.desks.clock)
            return self._books[key]

    def waive(self, peer: Peer, name: str, item: str, reason: str) -> tuple[Waiver, ...]:
        """``WaiverBook.grant``: only GNSS and sync, a typed reason, audited with the peer's operator."""
        if not peer.operator:
            raise ConfigError("operator.name: set [operator] name; every waiver is audited with it")
        book = self._book(peer, name)
        book.grant(item, peer.operator, reason)
        return tuple(book.waivers)

    def withdraw(self, peer: Peer, name: str, item: str) -> tuple[Waiver, ...]:
        book = self._book(peer, name)
        book.withdraw(item, peer.operator)
        return tuple(book.waivers)

    def held(self, peer: Peer, name: str) -> tuple[Waiver, ...]:
        return tuple(self._book(peer, name).waivers)

    def all_held(self, peer: Peer) -> dict[str, tuple[Waiver, ...]]:
        return {name: self.held(peer, name) for name in self.desks.desk(peer).state.capsules}

    def void(self, name: str) -> None:
        """A reset starts the next attempt: nobody's waivers of the last one stand."""
        with self._lock:
            for (_, capsule), book in self._books.items():
                if capsule == name:
                    book.clear()
