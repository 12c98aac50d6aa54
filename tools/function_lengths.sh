#!/usr/bin/env bash
# Lines per function in C++ sources written in this repository's brace style (a function body opens with "{" alone on
# a line after the line that closes its signature). Prints "lines file:line signature", longest first.
# Usage: tools/function_lengths.sh [FILE...]   (default: fitting/src/*.cpp); e.g. tools/function_lengths.sh | head
# Counts from the last signature line to the closing brace; comments and string contents are ignored for braces.
set -euo pipefail
cd "$(dirname "$0")/.."
files=("$@")
[ ${#files[@]} -gt 0 ] || files=(fitting/src/*.cpp)
for f in "${files[@]}"; do
	awk '
	function count(s, c,   n, i) { n = 0; for (i = 1; i <= length(s); i++) if (substr(s, i, 1) == c) n++; return n }
	{
		line = $0
		gsub(/\/\/.*$/, "", line); gsub(/"([^"\\]|\\.)*"/, "\"\"", line); gsub(/'"'"'([^'"'"'\\]|\\.)*'"'"'/, "0", line)
		if (!inside && line ~ /^[ \t]*\{[ \t]*$/ && prev ~ /\)/ && prev !~ /^[ \t]*(if|for|while|switch|else|do|catch)([ \t(]|$)/ &&
			prev !~ /;[ \t]*$/ && prev !~ /=[ \t]*$/) {
			inside = 1; start = FNR - 1; name = prev; level = depth
		}
		depth += count(line, "{") - count(line, "}")
		if (inside && depth == level) {
			gsub(/^[ \t]+/, "", name)
			printf "%d %s:%d %s\n", FNR - start + 1, FILENAME, start, substr(name, 1, 100)
			inside = 0
		}
		if (line !~ /^[ \t]*$/) prev = line
	}' "$f"
done | sort -rn
