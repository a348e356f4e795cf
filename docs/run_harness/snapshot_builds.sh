# Sourced by rows_unchanged.sh and callgrind.sh: names the two builds and, unless SNAPSHOT=0,
# copies their binaries into $WORK (a build folder being rebuilt while a script runs would
# otherwise mix two binaries in one comparison; the binaries link the project statically), then
# points OLD_BUILD and NEW_BUILD at the copies.
echo "old build: $OLD_BUILD ($(git -C "$OLD_BUILD/.." rev-parse --short HEAD 2>/dev/null || echo '?'))"
echo "new build: $NEW_BUILD ($(git -C "$NEW_BUILD/.." rev-parse --short HEAD 2>/dev/null || echo '?')$(
  [ -n "$(git -C "$NEW_BUILD/.." status --porcelain --untracked-files=no 2>/dev/null)" ] && echo ', with uncommitted changes'))"
# Snapshot the binaries (SNAPSHOT=0 to run them in place): a build folder being rebuilt while this
# runs would otherwise mix two binaries in one comparison. The binaries link the project statically.
if [ "${SNAPSHOT:-1}" = 1 ]; then
  for tag in old new; do
    [ $tag = old ] && src=$OLD_BUILD || src=$NEW_BUILD
    dst=$WORK/build_$tag
    rm -rf "$dst" && mkdir -p "$dst/tools" "$dst/python" &&
      cp -p "$src/tools/stampede" "$src/tools/stampede-mpi" "$dst/tools/" &&
      { [ ! -d "$src/python/stampede" ] || cp -rp "$src/python/stampede" "$dst/python/"; } &&
      "$dst/tools/stampede" --version > /dev/null || { echo "cannot snapshot $src" >&2; exit 2; }
    echo "$tag binaries: $src, $(date -r "$src/tools/stampede" '+%F %T'), sha256 $(sha256sum "$dst/tools/stampede" | cut -c1-16) (stampede), copied to $dst"
  done
  OLD_BUILD=$WORK/build_old
  NEW_BUILD=$WORK/build_new
fi
