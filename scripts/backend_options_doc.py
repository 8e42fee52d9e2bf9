"""Write docs/backend_options.md from the backends' typed options models (`rtchannel.backends.options`).

    python scripts/backend_options_doc.py [--check]

--check only compares (exit status 1 if the page is out of date), as tests/test_backend_options.py does.
"""
import argparse
import sys
from pathlib import Path

from processing.atomic import write_text_atomic
from rtchannel.backends.options import options_doc

PAGE = Path(__file__).resolve().parents[1] / "docs" / "backend_options.md"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="compare only")
    args = ap.parse_args(argv)
    text = options_doc() + "\n"
    if args.check:
        same = PAGE.is_file() and PAGE.read_text() == text
        print(f"{PAGE}: {'up to date' if same else 'out of date'}")
        return 0 if same else 1
    write_text_atomic(PAGE, text)
    print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
