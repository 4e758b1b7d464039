"""workbench.errors.one_line: any error on one line, as the CLI, runs and kit show it."""

from __future__ import annotations

from workbench.errors import ConfigError, one_line


class Unprintable(Exception):
    def __str__(self) -> str:
        raise RuntimeError("no")


def test_lines_are_joined_after_the_type_name() -> None:
    assert one_line(ValueError("first\n\n  second  \n")) == "ValueError: first | second"
    assert one_line(ConfigError("bad\nvalue")) == "ConfigError: bad | value"
    assert one_line(KeyError("k")) == "KeyError: 'k'"
    assert one_line(ValueError()) == "ValueError"


def test_without_the_type_for_messages_written_for_the_user() -> None:
    assert one_line(ConfigError("bad\nvalue"), with_type=False) == "bad | value"
    assert one_line(ConfigError(), with_type=False) == "ConfigError"


def test_notes_are_left_out_and_a_broken_str_is_survived() -> None:
    error = ValueError("the message")
    error.add_note("a note")
    assert one_line(error) == "ValueError: the message"
    assert one_line(Unprintable()) == f"{__name__}.Unprintable: <exception str() failed>"
