"""``python -m agents.reference_pages``: write the generated reference pages and the task
pictures."""

from agents.reference_pages import main

raise SystemExit(main())
