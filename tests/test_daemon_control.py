"""The control socket's request parsing (autopilot.daemon.control): pure, bytes in, request or refusal out."""


def test_a_ctl_request_with_a_field_given_twice_is_refused():
    """Found by fault injection: {"command": "status", "command": "pause"} paused the boat (JSON's last key wins)."""
    from autopilot.daemon.control import parse_request

    assert parse_request(b'{"command": "status", "command": "pause"}') == (
        None, "malformed request: field 'command' given twice")
    assert parse_request(b'{"command": "hold", "heading_deg": 90}') == ({"command": "hold", "heading_deg": 90}, None)
