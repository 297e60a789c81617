"""kukaid's command-line front end (installed as the package ``kukaid_cli``)."""
