"""Renders a report page in headless Chromium, as an engineer's browser would.

    python render.py PAGE.html SHOT.png [CHROMIUM]

Opens the page from its file with Playwright driving Debian's Chromium (the `playwright`
package's own browsers are not used), waits for it to load, takes a full-page screenshot
and prints one JSON object: the console messages as [type, text], the uncaught page
errors, and every URL the page requested (the page itself included). The caller judges them.
"""

import json
import pathlib
import sys

from playwright.sync_api import sync_playwright

# The flags the machine's probe found Chromium needs here: no sandbox as root, and no
# background connections to Google's hosts, which this closed network refuses.
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def main():
    page_path = pathlib.Path(sys.argv[1]).resolve()
    shot = sys.argv[2]
    chromium = sys.argv[3] if len(sys.argv) > 3 else "/usr/bin/chromium"
    seen = {"console": [], "errors": [], "requests": []}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.on("console", lambda m: seen["console"].append([m.type, m.text]))
        page.on("pageerror", lambda e: seen["errors"].append(str(e)))
        page.on("request", lambda r: seen["requests"].append(r.url))
        page.goto(page_path.as_uri(), wait_until="load")
        page.screenshot(path=shot, full_page=True)
        seen["title"] = page.title()
        browser.close()
    print(json.dumps(seen))


if __name__ == "__main__":
    main()
