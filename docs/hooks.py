"""MkDocs hook: a page's link to a README section that moved into the manual
(``../README.md#doppler-ego-beyond-the-paper``) points at the section's place in the manual,
so pages written against the long README keep working links in the built site."""

import re

#: README anchor -> its page and anchor in the manual
MOVED = {
    "doppler-ego-beyond-the-paper": "methods.md#doppler-ego-beyond-the-paper",
    "metrics": "metrics.md",
    "real-datasets": "datasets.md",
    "adding-a-method": "extending.md#adding-a-method",
    "adding-a-loader": "extending.md#adding-a-loader",
    "adding-a-metric": "extending.md#adding-a-metric",
    "experiments": "experiments.md",
    "methods": "methods.md",
    "results-layout": "results.md#results-layout",
}
LINK = re.compile(r"\]\((?:\.\./)+README\.md#([\w-]+)\)")


def on_page_markdown(markdown, page, config, files):
    def repl(match):
        target = MOVED.get(match.group(1))
        if target is None:
            return match.group(0)  # left as it is: the build reports it as broken
        depth = page.file.src_uri.count("/")
        return f"]({'../' * depth}{target})"

    return LINK.sub(repl, markdown)
