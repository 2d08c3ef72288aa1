#!/bin/bash
# usage: bash .ci/layout_counts.sh COMMIT: how the tree at COMMIT is laid out (files per package root,
# files over 700 lines, private names imported across modules, registries, lines, fmt markers)
C=$1
echo "commit $C"
for d in estimators agents vrloco_env; do
  echo "$d/: $(git ls-tree --name-only $C $d/ | grep -c '\.py$') .py files at its root, $(git ls-tree -r --name-only $C $d/ | grep -c '\.py$') in all"
done
echo "source files over 700 lines: $(for f in $(git ls-tree -r --name-only $C estimators vrloco_env agents | grep '\.py$'); do n=$(git show $C:$f | wc -l); [ $n -gt 700 ] && echo "$f:$n"; done | tr '\n' ' ')"
echo "private names imported from a sibling module (from x import _y): $(for f in $(git ls-tree -r --name-only $C estimators vrloco_env agents | grep '\.py$'); do git show $C:$f; done | grep -cE '^from (estimators|vrloco_env|agents)[.a-z_0-9]* import .*\b_[a-z]')"
echo "Registry( instances: $(for f in $(git ls-tree -r --name-only $C estimators vrloco_env agents | grep '\.py$'); do git show $C:$f; done | grep -cE "^[A-Z_]+ *(:.*)?= *(Stage)?Registry\\(")"
echo "lines of Python (estimators, vrloco_env, agents): $(for f in $(git ls-tree -r --name-only $C estimators vrloco_env agents | grep '\.py$'); do git show $C:$f; done | wc -l)"
echo "'# fmt: skip' markers: $(for f in $(git ls-tree -r --name-only $C | grep '\.py$'); do git show $C:$f; done | grep -c 'fmt: skip')"
