#!/usr/bin/env bash
# Where app/ and io/'s lines come from since the commit before the run-harness refactor (issue 54's
# must-show 3, "app/ and io/ shrink"): `git blame -w -M -C` of every .cpp/.hpp in app/ and io/ at
# HEAD over BASE..HEAD, each surviving line attributed to the commit that wrote it (moves and copies
# between files followed, so code moved by the refactor keeps its older commit), and the commits
# grouped by the issue they served: 55 (reliability: fuzz findings, pair checks, failed cells) and
# 56 (metadetection on survey data) as listed below, everything else 54 (the harness).
#
#   docs/run_harness/line_attribution.sh [BASE]      (default 842e248)
set -eu
BASE=${1:-842e248}
cd "$(git rev-parse --show-toplevel)"
ISSUE55="1564e79 a34d7a7 061b50f a7fb5fc bb6efa2 6710331 090beb1 3af2d89 6f595d2 eea444a d94ea88 fd063d8 e567141
e5403e7 9e14f58 5217f74 71336f1"
ISSUE56="d799bb1 2bbb7d1 8a76eac 134aeca b481ef4 6a03991 67683b1 f278ae7 037dddd 6b84c1a 0eb71d7 ab8c07d 636414d
f253b7c"
echo "HEAD $(git rev-parse --short HEAD), base $BASE"
for folder in app io; do
  before=$(git ls-tree -r --name-only "$BASE" "$folder/" | grep -E '\.(c|h)pp$' | while read -r f; do git show "$BASE:$f"; done | wc -l)
  now=$(git ls-files "$folder/" | grep -E '\.(c|h)pp$' | xargs cat | wc -l)
  declare -A by=([base]=0 [54]=0 [55]=0 [56]=0)
  while read -r n commit; do
    short=${commit:0:7}
    if [ "$short" = "${BASE:0:7}" ] || git merge-base --is-ancestor "$commit" "$BASE"; then k=base
    elif [[ " $ISSUE55 " == *" $short "* ]] || [[ "$ISSUE55" == *"$short"* ]]; then k=55
    elif [[ "$ISSUE56" == *"$short"* ]]; then k=56
    else k=54; fi
    by[$k]=$(( ${by[$k]} + n ))
  done < <(git ls-files "$folder/" | grep -E '\.(c|h)pp$' | while read -r f; do
             git blame -w -M -C --line-porcelain "$BASE..HEAD" -- "$f" | grep -E '^[0-9a-f]{40} ' | cut -c1-40
           done | sort | uniq -c)
  echo "$folder: $before lines at $BASE, $now now: ${by[base]} of $BASE's kept, $(( before - by[base] )) removed;" \
       "added by issue 54 ${by[54]}, issue 55 ${by[55]}, issue 56 ${by[56]};" \
       "without 55 and 56: $(( now - by[55] - by[56] )) ($(( now - by[55] - by[56] - before )) against $BASE)"
  unset by
done
