"""``python -m autosar_cli``: the ``autosar`` command, as ``python -m autosar_cli.cli`` runs it."""

from autosar_cli import install_interrupt_handlers

install_interrupt_handlers()  # as the `autosar` console script has them: SIGTERM cleans up and says so

from autosar_cli.cli import main  # noqa: E402 - after the handlers, as the console script's import installs them

main()
