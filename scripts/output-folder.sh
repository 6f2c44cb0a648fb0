# Sourced by the example scripts: prepare_output_folder SCRIPT DIR makes DIR ready for SCRIPT's outputs without ever
# deleting what the script did not write. DIR is created if missing; an empty DIR is used as it is; a DIR that holds
# an earlier run of the same script (its marker file .written-by-SCRIPT) is emptied first; any other DIR is refused.
prepare_output_folder() {
  local script="$1" dir="$2"
  local marker="$dir/.written-by-$script"
  if [ -e "$dir" ] && [ ! -d "$dir" ]; then
    echo "$script: $dir exists and is not a folder" >&2
    return 1
  fi
  if [ -d "$dir" ] && [ -n "$(ls -A "$dir")" ]; then
    if [ ! -f "$marker" ]; then
      echo "$script: $dir is not empty and was not written by $script; give another folder" >&2
      return 1
    fi
    find "$dir" -mindepth 1 -delete
  fi
  mkdir -p "$dir"
  : >"$marker"
}
