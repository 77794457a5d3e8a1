// Staged output directories, paths kept inside them and outputs kept off inputs (output_dir.h).
#include "rodfit/io/output_dir.h"

#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <system_error>

#include "rodfit/io/errors.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;

std::string ErrnoMessage(int err) { return std::generic_category().message(err); }

// A name for messages: a hostile name is cut short, and shown quoted.
std::string Quoted(const std::string& name) { return "'" + ClipForMessage(name) + "'"; }

}  // namespace

std::string PathInside(const std::string& dir, const std::string& relative,
                       const std::string& what) {
  auto refuse = [&](const std::string& why) {
    throw InputError(dir, 0, "", what + " " + Quoted(relative) + " " + why);
  };
  if (relative.empty()) refuse("is empty");
  if (relative.find('\0') != std::string::npos) refuse("contains a NUL byte");
  if (relative.find('\\') != std::string::npos) refuse("contains a backslash");
  const fs::path rel(relative);
  if (rel.has_root_path()) refuse("is an absolute path; it must stay inside the directory");
  for (const fs::path& part : rel) {
    if (part == "..") refuse("leaves the directory ('..')");
    if (part == ".") refuse("has a '.' component");
  }
  const fs::path base = fs::path(dir.empty() ? "." : dir).lexically_normal();
  const fs::path joined = (base / rel).lexically_normal();
  // Belt and braces: whatever the checks above missed, the joined path must stay below dir.
  const fs::path back = joined.lexically_relative(base);
  if (back.empty() || *back.begin() == ".." || back == ".") refuse("leaves the directory");
  return joined.string();
}

std::vector<InputFile> ExperimentInputs(const Experiment& experiment, bool with_data_files) {
  std::vector<InputFile> inputs = {{experiment.path, "the experiment"}};
  for (size_t c = 0; c < experiment.cases.size(); ++c) {
    const std::string key = "cases[" + std::to_string(c) + "]";
    const auto& observations = experiment.cases[c].observations;
    for (size_t o = 0; o < observations.size(); ++o) {
      const std::string entry = key + ".observations[" + std::to_string(o) + "]";
      if (with_data_files && !observations[o].file.empty())
        inputs.emplace_back(observations[o].file, "the data file of " + entry);
      if (!observations[o].camera.empty())
        inputs.emplace_back(observations[o].camera, "the camera of " + entry);
      // A mask is an input even to synth, which writes the images but never their masks.
      if (!observations[o].mask.empty())
        inputs.emplace_back(observations[o].mask, "the mask of " + entry);
    }
    if (c >= experiment.scene.cases.size()) continue;
    const LoadCase& load_case = experiment.scene.cases[c];
    if (load_case.start.kind == StartShape::Kind::kPoints)
      inputs.emplace_back(load_case.start.file, "the start shape of " + key);
    // A moving scene's series and initial velocities are read by the run as well.
    for (const DrivenPoint& drive : load_case.drives)
      inputs.emplace_back(drive.path.file, "the drive path of " + key + " (" + drive.point + ")");
    inputs.emplace_back(load_case.tip_load.file, "the tip load of " + key);
    inputs.emplace_back(load_case.initial.file, "the initial velocity file of " + key);
  }
  return inputs;
}

void RefuseOverwritingInput(const std::string& output, const std::vector<InputFile>& inputs) {
  for (const auto& [input, what] : inputs) {
    if (input.empty()) continue;
    std::error_code ec_out, ec_in;
    bool same = false;
    if (fs::exists(output, ec_out) && fs::exists(input, ec_in)) {
      // Links and different spellings of one file are the same file.
      same = fs::equivalent(output, input, ec_out) && !ec_out;
    } else {
      const fs::path a = fs::weakly_canonical(output, ec_out);
      const fs::path b = fs::weakly_canonical(input, ec_in);
      same = !ec_out && !ec_in && a == b;
    }
    if (same) {
      throw InputError(output, 0, "",
                       "is " + what + " (" + input + "), an input of this run; write the output "
                       "elsewhere");
    }
  }
}

void CheckOutputFile(const std::string& output, const std::vector<InputFile>& inputs) {
  if (output.empty()) throw InputError("''", 0, "", "the output path is empty: give a file name");
  std::error_code ec;
  const fs::file_status s = fs::symlink_status(output, ec);
  if (fs::exists(s) && !fs::is_regular_file(s) && !fs::is_symlink(s)) {
    throw InputError(output, 0, "",
                     std::string("exists and is not a file (") +
                         (fs::is_directory(s) ? "a directory" : "a device, FIFO or socket") +
                         "); not replaced, nothing was written");
  }
  RefuseOverwritingInput(output, inputs);
}

void CheckOutputDirectory(const std::string& dir, const std::vector<std::string>& names,
                          const std::vector<InputFile>& inputs) {
  if (dir.empty())
    throw InputError("''", 0, "", "the output directory's path is empty: give a directory");
  std::error_code ec;
  const fs::file_status s = fs::status(dir, ec);
  if (fs::exists(s) && !fs::is_directory(s))
    throw InputError(dir, 0, "", "exists and is not a directory");
  for (const std::string& name : names)
    CheckOutputFile(PathInside(dir, name, "output file name"), inputs);
}

StagedDirectory::StagedDirectory(const std::string& target, bool stage_inside)
    : target_(target) {
  // An empty -o would write into the working directory: refused, as no path at all.
  if (target.empty())
    throw InputError("''", 0, "", "the output directory's path is empty: give a directory");
  std::error_code ec;
  fs::path path = fs::absolute(target.empty() ? fs::path(".") : fs::path(target), ec);
  if (ec) throw InputError(target, 0, "", "not a usable directory name: " + ec.message());
  path = path.lexically_normal();
  if (!path.has_filename()) path = path.parent_path();  // "out/" is "out"
  if (path == path.root_path() || !path.has_parent_path()) {
    throw InputError(target, 0, "", "cannot write into the file system's root; give a directory");
  }
  target_path_ = path.string();
  const fs::file_status status = fs::status(path, ec);
  if (fs::exists(status) && !fs::is_directory(status)) {
    throw InputError(target, 0, "", "exists and is not a directory");
  }
  // The parent directories the staging directory needs; removed again unless the run succeeds.
  std::vector<fs::path> missing;
  for (fs::path p = path.parent_path(); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.root_path()) break;
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (::mkdir(it->c_str(), 0777) != 0 && errno != EEXIST) {
      const int err = errno;
      RemoveStaging();
      throw InputError(target, 0, "", "cannot create directory " + it->string() + ": " +
                                          ErrnoMessage(err));
    }
    created_parents_.push_back(it->string());
  }
  // A name no other run uses: mkdir fails rather than sharing a directory with another process.
  // Beside the target; inside an existing target when its parent is not writable (`-o .` in a
  // folder of a read-only tree), which keeps the final renames on one file system all the same.
  static std::atomic<unsigned> counter{0};
  const std::string base = path.filename().string();
  fs::path where = stage_inside && fs::is_directory(status) ? path : path.parent_path();
  for (int attempt = 0; attempt < 100 && staging_.empty(); ++attempt) {
    const std::string candidate =
        (where / ("." + base + ".tmp." + std::to_string(::getpid()) + "." +
                  std::to_string(counter++)))
            .string();
    if (::mkdir(candidate.c_str(), 0777) == 0) {
      staging_ = candidate;
    } else if ((errno == EACCES || errno == EPERM || errno == EROFS) &&
               where != path && fs::is_directory(status)) {
      where = path;
    } else if (errno != EEXIST) {
      const int err = errno;
      RemoveStaging();
      throw InputError(target, 0, "",
                       "cannot create a temporary directory for it: " + ErrnoMessage(err));
    }
  }
  if (staging_.empty()) {
    RemoveStaging();
    throw InputError(target, 0, "", "cannot write: no free temporary directory name");
  }
}

StagedDirectory::~StagedDirectory() {
  if (committed_) {
    Release();
  } else {
    RemoveStaging();
  }
}

void StagedDirectory::RemoveStaging() {
  std::error_code ec;
  if (!staging_.empty()) {
    fs::remove_all(staging_, ec);
    fs::remove_all(staging_ + ".old", ec);
  }
  if (committed_) return;
  // Innermost first; fs::remove leaves a directory that is no longer empty.
  for (auto it = created_parents_.rbegin(); it != created_parents_.rend(); ++it) fs::remove(*it, ec);
  created_parents_.clear();
}

std::string StagedDirectory::FinalPath(const std::string& relative) const {
  return PathInside(target_path_, relative, "output file name");
}

void StagedDirectory::Write(const std::string& relative, const std::string& contents,
                            const std::string& what) {
  if (committed_) throw std::logic_error("StagedDirectory::Write after Commit");
  PathInside(target_, relative, what);  // refused in the user's own words for the target
  const fs::path staged = PathInside(staging_, relative, what);
  const std::string final_path = FinalPath(relative);
  // An input is refused at once; what else is in the way (a directory, a FIFO) at the commit,
  // which checks every file before any is moved.
  RefuseOverwritingInput(final_path, inputs_);
  std::error_code ec;
  fs::create_directories(staged.parent_path(), ec);
  if (ec) throw InputError(final_path, 0, "", "cannot write: " + ec.message());
  std::FILE* out = std::fopen(staged.c_str(), "wb");
  if (out == nullptr) throw InputError(final_path, 0, "", "cannot write: " + ErrnoMessage(errno));
  const bool written = std::fwrite(contents.data(), 1, contents.size(), out) == contents.size();
  const int err = errno;
  if (std::fclose(out) != 0 || !written) {
    throw InputError(final_path, 0, "", "cannot write: " + ErrnoMessage(written ? errno : err));
  }
  for (const std::string& f : files_) {
    if (f == relative) return;
  }
  files_.push_back(relative);
}

void StagedDirectory::Commit(bool undoable) {
  if (committed_) return;
  std::error_code ec;
  if (!fs::exists(target_path_, ec)) {
    // The whole directory at once.
    if (std::rename(staging_.c_str(), target_path_.c_str()) == 0) {
      committed_ = true;
      renamed_whole_ = true;
      undoable_ = undoable;
      if (!undoable_) Release();
      return;
    }
    if (errno != EEXIST && errno != ENOTEMPTY) {
      throw InputError(target_, 0, "", "cannot create: " + ErrnoMessage(errno));
    }
    // Someone made the directory meanwhile: go file by file as below.
  }
  // Every final path checked before anything moves: no directory (or other non-file) in the way.
  for (const std::string& rel : files_) {
    const fs::path final_path = FinalPath(rel);
    for (fs::path p = final_path.parent_path(); p.string().size() > target_path_.size();
         p = p.parent_path()) {
      const fs::file_status s = fs::status(p, ec);
      if (fs::exists(s) && !fs::is_directory(s)) {
        throw InputError(p.string(), 0, "", "is in the way of " + final_path.string() +
                                                " (not a directory); nothing was written");
      }
    }
    // Again at the commit: the path may have changed since the file was staged.
    CheckOutputFile(final_path.string(), inputs_);
  }
  // Moved one by one; each replaced file kept aside until all are in (and until RollBack() can
  // no longer be asked for), so a failure puts the directory back as it was.
  const fs::path old_dir = staging_ + ".old";
  moved_.clear();
  made_dirs_.clear();
  for (size_t k = 0; k < files_.size(); ++k) {
    const fs::path final_path = FinalPath(files_[k]);
    const fs::path staged = PathInside(staging_, files_[k], "output file name");
    std::vector<fs::path> missing;
    for (fs::path p = final_path.parent_path(); !fs::exists(p, ec); p = p.parent_path())
      missing.push_back(p);
    for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
      if (::mkdir(it->c_str(), 0777) != 0) {
        const int err = errno;
        UndoMoves();
        throw InputError(it->string(), 0, "", "cannot create directory: " + ErrnoMessage(err));
      }
      made_dirs_.push_back(it->string());
    }
    Moved m{final_path.string(), {}};
    if (fs::exists(fs::symlink_status(final_path, ec))) {
      m.old_copy = (old_dir / std::to_string(k)).string();
      fs::create_directories(old_dir, ec);
      if (std::rename(final_path.c_str(), m.old_copy.c_str()) != 0) {
        const int err = errno;
        UndoMoves();
        throw InputError(final_path.string(), 0, "", "cannot replace: " + ErrnoMessage(err));
      }
    }
    if (std::rename(staged.c_str(), final_path.c_str()) != 0) {
      const int err = errno;
      if (!m.old_copy.empty()) fs::rename(m.old_copy, final_path, ec);
      UndoMoves();
      throw InputError(final_path.string(), 0, "", "cannot write: " + ErrnoMessage(err));
    }
    moved_.push_back(m);
  }
  committed_ = true;
  undoable_ = undoable;
  if (!undoable_) Release();
}

void StagedDirectory::Release() noexcept {
  if (!committed_) return;
  undoable_ = false;
  if (renamed_whole_) staging_.clear();  // it is the target now
  renamed_whole_ = false;
  moved_.clear();
  made_dirs_.clear();
  RemoveStaging();
}

void StagedDirectory::UndoMoves() noexcept {
  std::error_code ignore;
  for (auto it = moved_.rbegin(); it != moved_.rend(); ++it) {
    fs::remove(it->final_path, ignore);
    if (!it->old_copy.empty()) fs::rename(it->old_copy, it->final_path, ignore);
  }
  for (auto it = made_dirs_.rbegin(); it != made_dirs_.rend(); ++it) fs::remove(*it, ignore);
  moved_.clear();
  made_dirs_.clear();
}

void StagedDirectory::RollBack() noexcept {
  if (!committed_ || !undoable_) return;
  std::error_code ignore;
  if (renamed_whole_) {
    // The target did not exist: it goes again, with the parents made for it.
    fs::remove_all(target_path_, ignore);
    renamed_whole_ = false;
  } else {
    UndoMoves();
  }
  committed_ = false;
  undoable_ = false;
  RemoveStaging();
}

void CommitAll(const std::vector<StagedDirectory*>& outputs) {
  for (size_t k = 0; k < outputs.size(); ++k) {
    try {
      outputs[k]->Commit(/*undoable=*/true);
    } catch (...) {
      for (size_t j = k; j-- > 0;) outputs[j]->RollBack();
      throw;
    }
  }
  for (StagedDirectory* output : outputs) output->Release();
}

}  // namespace rodfit
