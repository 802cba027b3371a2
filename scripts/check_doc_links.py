#!/usr/bin/python3
"""Checks the relative links of the documentation: every [text](target) and ![alt](target).

    scripts/check_doc_links.py [FILE.md ...]

Without arguments it checks README.md and every docs/**/*.md of the source tree. A target is
resolved against the folder of the file that holds it and must exist; a #fragment pointing into a
Markdown file must name one of its headings (GitHub's anchors: lower case, punctuation dropped,
spaces as hyphens). Links to other sites (http:, https:, mailto:) are not checked, nor links
inside code (fenced blocks and `spans`). Prints one line per broken link, file:line: target: why,
and exits 1 when there is one, else 0 silently.
"""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
LINK = re.compile(r'!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^()\s]+)(?:\s+"[^"]*")?\)')


def without_code(line):
    """The line with its `code spans` blanked out."""
    return re.sub(r'`+[^`]*`+', lambda m: ' ' * len(m.group(0)), line)


def links(path):
    """(line number, target) of every link outside code."""
    fenced = False
    for n, line in enumerate(path.read_text(encoding='utf-8').split('\n'), 1):
        if line.lstrip().startswith('```'):
            fenced = not fenced
            continue
        if fenced:
            continue
        for m in LINK.finditer(without_code(line)):
            yield n, m.group(1)


def anchors(path):
    """The anchors GitHub makes for the headings of a Markdown file."""
    seen = {}
    fenced = False
    for line in path.read_text(encoding='utf-8').split('\n'):
        if line.lstrip().startswith('```'):
            fenced = not fenced
            continue
        m = None if fenced else re.match(r'#{1,6}\s+(.*?)\s*#*\s*$', line)
        if not m:
            continue
        slug = re.sub(r'[^\w\- ]', '', m.group(1).lower()).replace(' ', '-')
        k = seen.get(slug, 0)
        seen[slug] = k + 1
        yield slug if k == 0 else f'{slug}-{k}'


def problems(path):
    for n, target in links(path):
        if re.match(r'[a-z][a-z0-9+.-]*:', target):  # another site
            continue
        file_part, _, fragment = target.partition('#')
        dest = (path.parent / file_part).resolve() if file_part else path
        where = f'{path.relative_to(ROOT)}:{n}: {target}'
        if not dest.exists():
            yield f'{where}: no such file or folder'
        elif fragment and dest.suffix == '.md' and fragment not in set(anchors(dest)):
            yield f'{where}: no heading with the anchor #{fragment} in {dest.relative_to(ROOT)}'


def main(argv):
    files = [pathlib.Path(a).resolve() for a in argv] or \
        [ROOT / 'README.md'] + sorted((ROOT / 'docs').rglob('*.md'))
    bad = [p for f in files for p in problems(f)]
    for p in bad:
        print(p)
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
