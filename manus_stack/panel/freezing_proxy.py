"""A loopback TCP relay that can go silent: a network that stops carrying anything while
every connection stays open (no FIN, no RST), as a Wi-Fi link that drops does. The page
reaches the panel through it in ``manus bench panel`` and the browser tests."""

from __future__ import annotations

import contextlib
import select
import socket
import threading

from manus_stack.ports import free_port


class FreezingProxy:
    """Relays ``127.0.0.1:<port>`` to ``127.0.0.1:<upstream>``; :attr:`frozen` holds
    every byte in both directions until it is cleared (the bytes then go on, late).

    Args:
        upstream: the port relayed to.
    """

    def __init__(self, upstream: int) -> None:
        self.upstream = upstream
        self.port = free_port()
        self.frozen = threading.Event()
        self._stop = threading.Event()
        self._listener = socket.create_server(("127.0.0.1", self.port))
        self._listener.settimeout(0.1)
        self._threads = [threading.Thread(target=self._accept, daemon=True)]
        self._threads[0].start()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                client, _ = self._listener.accept()
            except TimeoutError:
                continue
            server = socket.create_connection(("127.0.0.1", self.upstream))
            thread = threading.Thread(target=self._pump, args=(client, server), daemon=True)
            self._threads.append(thread)
            thread.start()

    def _pump(self, a: socket.socket, b: socket.socket) -> None:
        with a, b:
            while not self._stop.is_set():
                if self.frozen.is_set():
                    self._stop.wait(0.005)  # read nothing: the bytes wait in the kernel
                    continue
                ready, _, _ = select.select([a, b], [], [], 0.05)
                for src in ready:
                    try:
                        data = src.recv(65536)
                        if data:
                            (b if src is a else a).sendall(data)
                    except ConnectionError:  # a peer reset or closed: as a FIN, it ends here
                        data = b""
                    if not data:
                        return

    def freeze(self) -> None:
        """Go silent now (:attr:`frozen`; clear it to carry the held bytes on)."""
        self.frozen.set()

    def close(self) -> None:
        """Stop relaying and close every connection."""
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=2.0)
        with contextlib.suppress(OSError):
            self._listener.close()
