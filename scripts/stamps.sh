# Sourced by scripts/setup.sh and scripts/learned_policies.sh: the up-to-date checks of the
# model steps. A step runs again when its sources changed (hash_of); it then regenerates its
# data, and trains only when content_key of that data and of the trainer differs from the one the
# trained models were made from (a code change that leaves the data byte-identical keeps them).

# hash_of FILE...: one hash of the files' bytes.
hash_of() { cat "$@" | sha256sum | cut -d' ' -f1; }

# content_key PATH...: one hash of the names and bytes of the files (a directory: every file in
# it, in sorted order, named relative to it).
content_key() {
  local p f
  for p in "$@"; do
    if [ -d "$p" ]; then
      (cd "$p" && find . -type f | LC_ALL=C sort | while read -r f; do printf '%s\n' "$f"; cat "$f"; done)
    else
      printf '%s\n' "$p"
      cat "$p"
    fi
  done | sha256sum | cut -d' ' -f1
}

# stands DIR KEY: DIR holds models trained from the content KEY (its .data-key).
stands() { [ -d "$1" ] && [ "$(cat "$1/.data-key" 2>/dev/null)" = "$2" ]; }
