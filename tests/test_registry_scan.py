"""The registry's own scan of the installed entry points (``registry.scan_entry_points``, which
spares a run the import of ``importlib.metadata``) finds what ``importlib.metadata`` finds."""
from importlib import metadata

from lagamine_py import registry


def _reference(prefix="lagamine_py."):
    groups = ["console_scripts"] if prefix == "console_scripts" else \
        [f"lagamine_py.{k}" for k in registry.KINDS]
    return sorted((ep.group, ep.name, ep.value, f"{ep.dist.name} {ep.dist.version}")
                  for g in groups for ep in metadata.entry_points(group=g))


def test_scan_finds_the_entry_points_importlib_metadata_finds():
    ours = sorted((ep.group, ep.name, ep.value, registry.dist_origin(ep.dist_dir))
                  for ep in registry.scan_entry_points())
    assert ours == _reference() and len(ours) > 20


def test_scan_of_other_groups_too():
    """Another prefix (the console scripts): the parse is not tuned to our groups."""
    ours = sorted((ep.group, ep.name, ep.value, registry.dist_origin(ep.dist_dir))
                  for ep in registry.scan_entry_points("console_scripts"))
    assert ours == _reference("console_scripts") and ours


def _dist(root, dirname, name, version, entry_points):
    d = root / dirname
    d.mkdir()
    (d / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n\nbody\n")
    (d / "entry_points.txt").write_text(entry_points)
    return d


def test_first_distribution_of_a_name_wins_and_extras_comments_are_read(tmp_path):
    first, second = tmp_path / "a", tmp_path / "b"
    first.mkdir(), second.mkdir()
    text = ("# a comment\n[lagamine_py.laws]\nMINE = json:dumps [fast]\n; another\n"
            "[other.group]\nNOT = x:y\n")
    _dist(first, "my_plugin-1.0.dist-info", "my-plugin", "1.0", text)
    _dist(second, "My.Plugin-2.0.dist-info", "My.Plugin", "2.0", "[lagamine_py.laws]\nOLD = a:b\n")
    _dist(second, "other-3.egg-info", "other", "3", "[lagamine_py.checks]\nC = os.path:join\n")
    paths = [str(first), str(tmp_path / "missing"), str(second)]
    found = registry.scan_entry_points(path=paths)
    assert [(ep.group, ep.name, ep.value) for ep in found] == [
        ("lagamine_py.laws", "MINE", "json:dumps [fast]"), ("lagamine_py.checks", "C", "os.path:join")]
    assert registry.dist_origin(found[0].dist_dir) == "my-plugin 1.0"
    import json
    import os.path
    assert found[0].load() is json.dumps and found[1].load() is os.path.join


def test_a_zipped_distribution_hands_over_to_importlib(tmp_path):
    (tmp_path / "x.zip").write_bytes(b"")
    assert registry.scan_entry_points(path=[str(tmp_path / "x.zip")]) is None


def test_registry_falls_back_to_importlib_metadata(monkeypatch):
    """With a zipped distribution on sys.path the registry reads importlib.metadata: the same
    entry points and origins."""
    fresh = registry.Registry()
    monkeypatch.setattr(registry, "scan_entry_points", lambda *a, **k: None)
    got = sorted((ep.group, ep.name, ep.value, fresh._origin(ep))
                 for k in registry.KINDS for ep in fresh.entry_points(k))
    assert got == _reference()
