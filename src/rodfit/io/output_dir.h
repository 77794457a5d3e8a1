// Where a run's outputs may go: every file of a run is staged in a temporary directory
// beside the target and moved into place only when the run succeeds, no output path leaves its
// output directory, and no output is one of the run's own inputs. Errors are InputErrors naming
// the output path.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "rodfit/io/experiment.h"

namespace rodfit {

/// `relative` joined to `dir`, refused (InputError naming `dir` and `what`) unless it is a plain
/// relative path that stays inside `dir`: not empty, not absolute, no `..` and no `.` component,
/// no backslash or NUL. `what` says where the name came from, e.g. "case name 'x'".
std::string PathInside(const std::string& dir, const std::string& relative,
                       const std::string& what);

/// An input of a run: its path and what it is, for messages ("the experiment", "the camera of
/// cases[0].observations[1]").
using InputFile = std::pair<std::string, std::string>;

/// The experiment file and every file it names that a run reads: observation data files (unless
/// `with_data_files` is false: synth writes them), camera files, masks, start shapes and a moving
/// scene's files (drive paths, tip load series, initial velocities or second frames), paths as
/// resolved by the reader.
std::vector<InputFile> ExperimentInputs(const Experiment& experiment, bool with_data_files = true);

/// Throws InputError naming `output` and the input when `output` is the same file as one of
/// `inputs` (std::filesystem::equivalent when both exist, else the same weakly canonical path).
/// Call it before anything is written.
void RefuseOverwritingInput(const std::string& output, const std::vector<InputFile>& inputs);

/// The output rule of every command and library writer, for one file a run will write: not an
/// empty path, not one of `inputs` (RefuseOverwritingInput), and nothing that exists there but a
/// regular file or a symbolic link (a directory, device, FIFO or socket is refused: the rename
/// would replace it; a link is replaced, never followed). Throws InputError naming `output`.
/// StagedDirectory applies it to every file it writes and again at its commit; commands call it
/// before their work starts so that a refused output costs nothing.
void CheckOutputFile(const std::string& output, const std::vector<InputFile>& inputs);

/// CheckOutputFile for the files `names` a run will write into directory `dir`, before its work
/// starts: `dir` not empty and not an existing non-directory, each name kept inside it.
void CheckOutputDirectory(const std::string& dir, const std::vector<std::string>& names,
                          const std::vector<InputFile>& inputs);

/// A run's output directory, written all at once. Files are written into a fresh hidden
/// directory beside `target` (`.NAME.tmp.PID.N`, so the final renames stay on one file system;
/// inside an existing `target` when its parent is not writable);
/// Commit() moves them into place: a target that does not exist is the staged directory renamed,
/// one that exists gets each file renamed over its old one (other files stay), and a failure on
/// the way puts back every file it had replaced. Without Commit(), or when it fails, the
/// destructor removes the staging directory and any parent directories it created, so the
/// output location is left as it was. Commit(true) keeps the files it replaced (and the staging
/// directory) until Release() or the destructor, so that RollBack() can undo the commit when
/// another output of the run then fails (CommitAll).
class StagedDirectory {
 public:
  /// Throws InputError when `target` is empty, exists and is not a directory, or the staging
  /// directory cannot be made. `stage_inside`: stage inside `target` when it exists (for single files
  /// written into a directory of the user's, like the profile, which then get no temporary
  /// directory beside that directory).
  explicit StagedDirectory(const std::string& target, bool stage_inside = false);
  ~StagedDirectory();
  StagedDirectory(const StagedDirectory&) = delete;
  StagedDirectory& operator=(const StagedDirectory&) = delete;

  /// The run's inputs: no file of this directory may be one of them (CheckOutputFile, checked by
  /// Write and again by Commit). Give them before the first Write.
  void SetInputs(std::vector<InputFile> inputs) { inputs_ = std::move(inputs); }
  /// Stages `relative` (checked with PathInside and CheckOutputFile; `what` for its message)
  /// with `contents`.
  void Write(const std::string& relative, const std::string& contents,
             const std::string& what = "output file name");
  /// The final path of a staged or to-be-staged file, for RefuseOverwritingInput and messages.
  std::string FinalPath(const std::string& relative) const;
  /// Moves every staged file into the target; throws InputError (target as it was) on failure.
  /// `undoable`: keep what RollBack() needs until Release().
  void Commit(bool undoable = false);
  /// Undoes a successful Commit(true): the files it moved in are removed, the ones it replaced
  /// put back, the directories it created removed. Best effort, never throws; nothing to do
  /// before a Commit(true) or after Release().
  void RollBack() noexcept;
  /// After Commit(true): the commit stands; the replaced files and the staging directory go.
  void Release() noexcept;

 private:
  struct Moved {
    std::string final_path, old_copy;  // old_copy empty: there was no file
  };
  void RemoveStaging();
  void UndoMoves() noexcept;

  std::string target_;       // as given, for messages
  std::string target_path_;  // absolute, normalised, no trailing separator
  std::string staging_;
  std::vector<std::string> created_parents_;  // made for the staging directory, innermost last
  std::vector<std::string> files_;            // relative paths, in the order written
  std::vector<InputFile> inputs_;             // SetInputs: none of them is overwritten
  std::vector<Moved> moved_;                  // by the commit, in order
  std::vector<std::string> made_dirs_;        // by the commit, outermost first
  bool renamed_whole_ = false;                // the commit renamed the staging directory
  bool undoable_ = false;                     // Commit(true), not yet released
  bool committed_ = false;
};

/// Commits `outputs` in order; when one fails, rolls back those already committed (in reverse)
/// and rethrows, so the run's outputs are all in place or all as they were.
void CommitAll(const std::vector<StagedDirectory*>& outputs);

}  // namespace rodfit
