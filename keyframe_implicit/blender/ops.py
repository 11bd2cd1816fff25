"""Operators (thin: the logic lives in features, bake, output, validate)."""

import os
import time
from typing import TYPE_CHECKING

import bpy
from bpy.props import EnumProperty, FloatVectorProperty, IntProperty, StringProperty

from ..core.base.progress import Cancelled
from . import (bake, diagnostics, edits, farm, features, limits, preview, result_view,
               validate, work_cache)

if TYPE_CHECKING:
    from collections.abc import Iterable

    from .props import KFI_Settings

_OPTS = {"REGISTER", "UNDO"}
# Redo-panel ("Adjust Last Operation") hygiene: a property the panel fills in itself is not
# remembered for the next run (SKIP_SAVE) and, when it means nothing to the artist, not shown.
_INTERNAL = {"HIDDEN", "SKIP_SAVE"}


def _settings(context: bpy.types.Context) -> "KFI_Settings":
    return context.scene.keyframe_implicit


def _search_meshes(_op: bpy.types.Operator, context: bpy.types.Context, text: str) -> list[str]:
    """Search list of Add Keyframe's Object field: the scene's mesh objects."""
    text = text.lower()
    return [o.name for o in context.scene.objects if o.type == "MESH" and text in o.name.lower()]


def _kind(obj: bpy.types.Object) -> str:
    """"a Curve object", "an Empty": the object's type as the Add menu names it, with its article."""
    kind = obj.bl_rna.properties["type"].enum_items[obj.type].name
    return f"{'an' if kind[0] in 'AEIOU' else 'a'} {kind}"


class KFI_OT_add_keyframe(bpy.types.Operator):
    """Add a mesh object as a keyframe on a timeline frame"""

    bl_idname = "keyframe_implicit.add_keyframe"
    bl_label = "Add Keyframe"
    bl_options = _OPTS

    object_name: StringProperty(name="Object", default="", options={"SKIP_SAVE"},
                                search=_search_meshes,
                                description="Mesh object to add (empty: the active object)")
    frame: IntProperty(name="Frame", default=1, options={"SKIP_SAVE"},
                       description="Timeline frame, negative ones included (not set: the current frame)")

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Add the named (or active) mesh object as a keyframe on the frame given."""
        settings = _settings(context)
        name = self.object_name or (context.active_object.name if context.active_object else "")
        obj = context.scene.objects.get(name) if name else None
        if obj is None:
            missing = f"There is no object '{name}' in this scene" if name else "No object to add"
            self.report({"ERROR"}, f"{missing}: make a mesh object active (or pass object_name) "
                                   "and try again.")
            return {"CANCELLED"}
        if obj.type != "MESH":
            self.report({"ERROR"}, f"'{obj.name}' is {_kind(obj)}, not a mesh: pick a mesh object "
                                   "(or convert it with Object > Convert > Mesh).")
            return {"CANCELLED"}
        given = self.properties.is_property_set("frame")
        frame = self.frame if given else context.scene.frame_current
        self.object_name, self.frame = obj.name, frame  # what the redo panel shows
        if any(kf.frame == frame for kf in settings.keyframes):
            where = "the frame given" if given else "the current frame"
            self.report({"ERROR"}, f"Frame {frame} ({where}) already has a keyframe: pick another "
                                   "frame.")
            return {"CANCELLED"}
        # keep the list ordered by frame
        index = sum(1 for kf in settings.keyframes if kf.frame < frame)
        item = settings.keyframes.add()
        item.object = obj
        item.frame = frame
        last = len(settings.keyframes) - 1
        if index != last:
            settings.keyframes.move(last, index)
        settings.active_keyframe_index = index
        done = edits.keyframe_inserted(context.scene, settings, index,
                                       context.evaluated_depsgraph_get())
        msg = f"Keyframe {index + 1}: '{obj.name}' on frame {frame}."
        if done.proposed:
            features.select_only(context.view_layer, done.proposed)
            how = ("where the bake moves that material" if done.from_bake else
                   "between each pair's two points, on its surface")
            msg += (f" Split the {validate.count(done.split, 'feature pair')} through it in two: "
                    f"proposed {len(done.proposed)} Empties on it, {how}, selected for review.")
        self.report({"INFO"}, msg)
        return {"FINISHED"}


class KFI_OT_remove_keyframe(bpy.types.Operator):
    """Remove a keyframe from the list (its object stays): the feature pairs through it are joined into pairs of its neighbours, the rest of its pairs deleted"""

    bl_idname = "keyframe_implicit.remove_keyframe"
    bl_label = "Remove Keyframe"
    bl_options = _OPTS

    index: IntProperty(name="Index", default=-1, options=_INTERNAL,
                       description="Keyframe to remove, from 0 (-1: the active one)")

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Remove a keyframe from the list (its object stays in the scene)."""
        settings = _settings(context)
        n = len(settings.keyframes)
        index = settings.active_keyframe_index if self.index < 0 else self.index
        if not 0 <= index < n:
            self.report({"ERROR"}, f"No keyframe {index + 1}: there are {n}.")
            return {"CANCELLED"}
        obj = settings.keyframes[index].object
        done = edits.keyframe_removed(context.scene, settings, index)
        settings.keyframes.remove(index)
        settings.active_keyframe_index = min(index, max(len(settings.keyframes) - 1, 0))
        preview.edited()
        msg = f"Removed keyframe {index + 1}" + (f" '{obj.name}'." if obj is not None else ".")
        if done.joined:
            msg += (f" Joined {validate.count(done.joined, 'feature pair')} through it into "
                    f"keyframes {index} \u2192 {index + 1} and removed their "
                    f"{validate.count(done.empties, 'Empty', 'Empties')} on it.")
        if done.deleted:
            why = " with no partner through it" if 0 < index < n - 1 else ""
            msg += f" Deleted {validate.count(done.deleted, 'feature pair')} that used it{why}."
        self.report({"INFO"}, msg)
        return {"FINISHED"}


class KFI_OT_move_keyframe(bpy.types.Operator):
    """Move a keyframe up or down in the list (its frame is swapped so the order stays by frame)"""

    bl_idname = "keyframe_implicit.move_keyframe"
    bl_label = "Move Keyframe"
    bl_options = _OPTS

    index: IntProperty(name="Index", default=-1, options=_INTERNAL,
                       description="Keyframe to move, from 0 (-1: the active one)")
    direction: EnumProperty(name="Direction", items=(("UP", "Up", ""), ("DOWN", "Down", "")))

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Move a keyframe up or down the list."""
        settings = _settings(context)
        n = len(settings.keyframes)
        index = settings.active_keyframe_index if self.index < 0 else self.index
        other = index - 1 if self.direction == "UP" else index + 1
        if not (0 <= index < n and 0 <= other < n):
            self.report({"WARNING"}, "Cannot move further in that direction.")
            return {"CANCELLED"}
        a, b = settings.keyframes[index], settings.keyframes[other]
        a.frame, b.frame = b.frame, a.frame
        settings.keyframes.move(index, other)
        settings.active_keyframe_index = other
        self.report({"INFO"}, "Moved; check the feature pairs of the segments around it.")
        return {"FINISHED"}


class KFI_OT_add_feature_pair(bpy.types.Operator):
    """Add a pair of feature points (two Empties) between keyframe i and i+1"""

    bl_idname = "keyframe_implicit.add_feature_pair"
    bl_label = "Add Feature Pair"
    bl_options = _OPTS

    segment: IntProperty(name="Segment", default=0, min=0,
                         description="The pair lies between keyframe 'segment' and 'segment + 1'")
    location_a: FloatVectorProperty(name="Location A", subtype="TRANSLATION", size=3,
                                    description="World position on keyframe i (default: 3D cursor)")
    location_b: FloatVectorProperty(name="Location B", subtype="TRANSLATION", size=3,
                                    description="World position on keyframe i+1 (default: 3D cursor)")
    name: StringProperty(name="Name", default="", description="Optional label shown in the names")

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Create a feature pair's two Empties on the segment's keyframes."""
        cursor = tuple(context.scene.cursor.location)
        for prop in ("location_a", "location_b"):
            if not self.properties.is_property_set(prop):
                setattr(self, prop, cursor)  # shown (and kept) in the redo panel
        try:
            pid = features.create_pair(context.scene, _settings(context), self.segment,
                                       tuple(self.location_a), tuple(self.location_b), self.name)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Added feature pair {pid}: move 'KFI {pid} A' onto keyframe "
                              f"{self.segment + 1} and 'KFI {pid} B' onto keyframe {self.segment + 2}.")
        return {"FINISHED"}


class KFI_OT_pair_selected(bpy.types.Operator):
    """Make the two selected Empties one feature pair (the active one goes on the later keyframe)"""

    bl_idname = "keyframe_implicit.pair_selected"
    bl_label = "Pair Selected"
    bl_options = _OPTS

    segment: IntProperty(name="Segment", default=-1, options=_INTERNAL,
                         description="Segment when the Empties are not parented to keyframe objects "
                                     "(-1: from their parents)")

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Make the two selected Empties a feature pair."""
        chosen = [o for o in context.selected_objects if o.type == "EMPTY"]
        if len(chosen) != 2:
            self.report({"ERROR"}, f"{len(chosen)} Empties selected: select exactly two "
                                   "(the active one on the later keyframe).")
            return {"CANCELLED"}
        active = context.active_object if context.active_object in chosen else chosen[1]
        first = chosen[0] if chosen[0] != active else chosen[1]
        try:
            pid = features.pair_empties(context.scene, _settings(context), first, active, self.segment)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Paired as feature pair {pid}.")
        return {"FINISHED"}


class _OnePair:
    """Mixin of the operators on one feature pair: its id, or the active feature Empty's
    pair from a menu or F3 (else a dialog asks for the id)."""

    bl_options = _OPTS

    pair: StringProperty(name="Pair", default="", description="Pair id, e.g. 0.3")

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        """Take the active feature Empty's pair, or ask for the id."""
        if not _resolve_pair(self, context):
            return context.window_manager.invoke_props_dialog(self)
        return self.execute(context)


class KFI_OT_remove_feature_pair(_OnePair, bpy.types.Operator):
    """Delete both Empties of a feature pair"""

    bl_idname = "keyframe_implicit.remove_feature_pair"
    bl_label = "Remove Feature Pair"

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Delete the pair's Empties; report if there is no such pair."""
        _resolve_pair(self, context)
        n = features.remove_pair(context.scene, self.pair)
        if not n:
            self.report({"ERROR"}, f"No feature pair {self.pair!r}: see the pairs in the sidebar.")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Removed feature pair {self.pair}.")
        return {"FINISHED"}


class KFI_OT_select_pair(_OnePair, bpy.types.Operator):
    """Select both Empties of a feature pair"""

    bl_idname = "keyframe_implicit.select_pair"
    bl_label = "Select Pair"

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Select the pair's two Empties."""
        _resolve_pair(self, context)
        try:
            features.select_pair(context.view_layer, context.scene, self.pair)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        return {"FINISHED"}


class KFI_OT_snap_features(bpy.types.Operator):
    """Move feature Empties that lie outside their keyframe's material onto the nearest point of its surface"""

    bl_idname = "keyframe_implicit.snap_features"
    bl_label = "Snap to Surface"
    bl_options = _OPTS

    empty: StringProperty(name="Empty", default="", options={"SKIP_SAVE"},
                          description="The feature Empty to snap (empty: every one more than one "
                                      "grid cell outside its keyframe)")

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Snap the named Empty, or every one the checks find off its surface."""
        depsgraph = context.evaluated_depsgraph_get()
        if self.empty:
            if not features.is_feature(context.scene.objects.get(self.empty)):
                self.report({"ERROR"}, f"No feature Empty '{self.empty}' in this scene.")
                return {"CANCELLED"}
            names = [self.empty]
        else:
            names = edits.off_surface(context.scene, depsgraph, validate.OFF_SURFACE_CELLS)
        moved = edits.snap(context.scene, names, depsgraph)
        if not moved:
            self.report({"INFO"}, "No feature Empty lies outside its keyframe: nothing moved.")
            return {"CANCELLED"}
        named = ", ".join(f"'{n}'" for n in moved[:validate.NAMED])
        rest = f" and {len(moved) - validate.NAMED} more" if len(moved) > validate.NAMED else ""
        self.report({"INFO"}, f"Snapped {validate.count(len(moved), 'feature Empty', 'feature Empties')}"
                              f" onto their keyframes' surfaces: {named}{rest}.")
        return {"FINISHED"}


def _failed(what: str, detail: str) -> str:
    """One sentence for a failed bake: the detail's own full stop is not doubled."""
    detail = detail.strip().rstrip(".;")
    return f"{what}: {detail}. The scene is unchanged."


def _resolve_pair(op: _OnePair, context: bpy.types.Context) -> bool:

    """No pair id given (menu, F3, script): take the active feature Empty's pair."""
    if not op.pair and features.is_feature(context.active_object):
        op.pair = str(context.active_object[features.PAIR])
    return bool(op.pair)


class KFI_MT_menu(bpy.types.Menu):
    """Object > Keyframe Implicit: every operator (this also puts them in F3 menu search)."""

    bl_idname = "KFI_MT_menu"
    bl_label = "Keyframe Implicit"

    def draw(self, context: bpy.types.Context) -> None:
        """Every operator of the add-on, the bake last."""
        layout = self.layout
        layout.operator("keyframe_implicit.add_keyframe")
        layout.operator("keyframe_implicit.remove_keyframe")
        layout.operator("keyframe_implicit.move_keyframe", text="Move Keyframe Up").direction = "UP"
        layout.operator("keyframe_implicit.move_keyframe", text="Move Keyframe Down").direction = "DOWN"
        layout.separator()
        layout.operator("keyframe_implicit.add_feature_pair")
        layout.operator("keyframe_implicit.pair_selected")
        layout.operator("keyframe_implicit.select_pair")
        layout.operator("keyframe_implicit.remove_feature_pair")
        layout.operator("keyframe_implicit.snap_features")
        layout.separator()
        layout.operator("keyframe_implicit.bake", icon="RENDER_ANIMATION")
        layout.operator("keyframe_implicit.export_farm_job", icon="NETWORK_DRIVE")
        layout.operator("keyframe_implicit.clear_cache", icon="TRASH")


def menu_func(self: bpy.types.Menu, context: bpy.types.Context) -> None:
    """Object > Keyframe Implicit: the add-on's menu in the Object menu."""
    self.layout.menu(KFI_MT_menu.bl_idname)


#: The BakeJob of the modal bake in progress (at most one): the panel shows its progress.
running = []
# Seconds between the modal bake's polls of its job. A poll costs next to nothing (nothing
# is redrawn unless the progress text changed), and a short step keeps a measured stall (the
# longest gap between polls beyond this step, `Diagnostics.max_poll_gap`) within 20 ms of the
# truth.
TIMER_STEP = 0.02
# Seconds of writing the result per turn of the main loop: pieces of `BakeJob.apply_steps` run
# until this is spent. Every turn that changes data redraws the 3D view (110-200 ms with
# software GL, benchmarks/README.md), so a small result is written in one turn, a large one
# over as few turns as keep each under 50 ms, the longest stall the add-on allows itself.
WRITE_BUDGET = 0.025


class KFI_OT_bake(bpy.types.Operator):
    """Bake the keyframes into one animated object: with Output Auto, shape keys when one mesh can follow the shape on every frame, else a mesh sequence (ESC cancels)"""

    bl_idname = "keyframe_implicit.bake"
    bl_label = "Bake"
    # No REGISTER: no redo panel, which would re-run a minutes-long bake blocking, without
    # progress or ESC. UNDO alone still makes the finished bake one undo step.
    bl_options = {"UNDO"}

    resolution: IntProperty(name="Resolution", default=0, min=0, options=_INTERNAL,
                            description="Grid resolution for this run (0: the scene setting)")

    _job = None
    _timer = None
    _shown = None  # the progress text on show
    _writer = None  # `BakeJob.apply_steps` once the worker is done
    _write_budget = WRITE_BUDGET

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        """Bake only one at a time, only a setup without blocking problems (the panel's
        list, `validate.problems`: read without the meshes, cheap on every redraw) and only
        at a Resolution that fits in memory (`limits.need`, the panel's line under
        Resolution); the button's tooltip says why not."""
        if running:
            cls.poll_message_set("A bake is already running (ESC cancels it).")
            return False
        if context.scene is None:
            return False
        errs = validate.errors(validate.problems(context.scene))
        if errs:
            more = f" (and {len(errs) - 1} more, in the panel)" if len(errs) > 1 else ""
            cls.poll_message_set(f"Cannot bake: {errs[0].message}{more}")
            return False
        found = limits.need(context.scene)
        if found is not None and found.over:
            text, _ = limits.line(found, context.scene.keyframe_implicit.resolution)
            cls.poll_message_set(f"Cannot bake: {text}")
            return False
        return True

    def _hints(self, context: bpy.types.Context, notes: "Iterable[str]" = ()) -> None:
        for p in validate.problems(context.scene):
            if p.severity == validate.WARNING:
                self.report({"WARNING"}, p.message)
        for note in notes:
            self.report({"WARNING"}, note)

    def execute(self, context: bpy.types.Context) -> set[str]:
        """Blocking bake (scripts, ``blender -b``, no window): `bake.bake_scene`."""
        preview.turn_off()
        notes = []
        try:
            obj = bake.bake_scene(context.scene, self.resolution,
                                  context.evaluated_depsgraph_get(), notes=notes)
        except Cancelled as exc:
            self.report({"WARNING"}, str(exc))
            return {"CANCELLED"}
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        except Exception as exc:  # the core failed: tell the user, leave the scene as it was
            self.report({"ERROR"}, _failed("Bake failed", bake.failure_text(exc)))
            return {"CANCELLED"}
        return self._done(context, obj, notes=notes)

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        """From the UI: read and check the scene once (`bake.collect`), then bake in the
        background while the modal handler polls (ESC cancels; `diagnostics.current`, when
        set, measures the polling)."""
        if context.window is None:
            return self.execute(context)
        preview.turn_off()
        try:
            inputs = bake.collect(context.scene, context.evaluated_depsgraph_get(), self.resolution)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._job = bake.BakeJob(inputs, diagnostics=diagnostics.current)
        running.append(self._job)
        self._job.start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(TIMER_STEP, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        self._status(context, "Baking: starting (ESC to cancel)")
        return {"RUNNING_MODAL"}

    def _status(self, context: bpy.types.Context, text: str | None) -> None:
        """Show ``text`` (None: nothing) in the status bar and in the panel, where the sidebars
        of the 3D views draw it; only these are redrawn, and only when the text changes."""
        if text == self._shown:
            return
        self._shown = text
        if context.workspace is not None:
            context.workspace.status_text_set(text)
        for area in context.screen.areas if context.screen is not None else ():
            if area.type == "VIEW_3D":
                for region in area.regions:
                    if region.type == "UI":
                        region.tag_redraw()

    def _finish(self, context: bpy.types.Context) -> None:
        """End the modal bake: its timer, progress and status go, it leaves `running`, and
        the 3D views are redrawn whole, so Bake (whose poll reads `running`) shows enabled
        at once, not when the pointer next moves, and the viewport shows the result."""
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if self._job in running:
            running.remove(self._job)
        self._status(context, None)
        for area in context.screen.areas if context.screen is not None else ():
            if area.type == "VIEW_3D":
                area.tag_redraw()

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        """Each turn of the main loop: ESC cancels; a timer event polls the job, shows its
        progress and, once it is done, writes the result a piece at a time."""
        job = self._job
        if event.type == "ESC" and event.value == "PRESS":
            if self._writer is not None:  # the result is half written: take it out again
                return self._stop_writing(context)
            job.cancel()
            self._status(context, "Baking: cancelling...")
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if not job.poll():
            fraction, message = job.status()
            text = f"Baking {100 * fraction:.0f}%: {message} (ESC to cancel)"
            if text != self._shown:
                context.window_manager.progress_update(int(100 * fraction))
                self._status(context, text)
            return {"RUNNING_MODAL"}
        if self._writer is None:
            if job.state == bake.CANCELLED:
                self._finish(context)
                self.report({"WARNING"}, "Bake cancelled; the scene is unchanged.")
                return {"CANCELLED"}
            if job.state == bake.FAILED:
                self._finish(context)
                self.report({"ERROR"}, _failed("Bake failed", job.error_message()))
                return {"CANCELLED"}
            self._writer = job.apply_steps(context.scene)
            self._status(context, "Baking: writing the result (ESC to cancel)")
        return self._write_step(context)

    def _write_step(self, context: bpy.types.Context) -> set[str]:
        """Pieces of writing the result (`BakeJob.apply_steps`) until `WRITE_BUDGET` is spent,
        then the main loop's turn."""
        t0 = time.perf_counter()
        try:
            while True:
                next(self._writer)
                if time.perf_counter() - t0 >= self._write_budget:
                    return {"RUNNING_MODAL"}
        except StopIteration as done:
            self._finish(context)
            return self._done(context, done.value, self._job.seconds, notes=self._job.notes)
        except Exception as exc:
            self._writer.close()  # (an error inside it has closed it already)
            self._finish(context)
            self.report({"ERROR"}, _failed("Writing the result failed", str(exc)))
            return {"CANCELLED"}

    def _stop_writing(self, context: bpy.types.Context) -> set[str]:
        self._writer.close()  # removes what it wrote
        self._finish(context)
        self.report({"WARNING"}, "Bake cancelled; the scene is unchanged.")
        return {"CANCELLED"}

    def _done(self, context: bpy.types.Context, obj: bpy.types.Object,
              seconds: float | None = None, notes: "Iterable[str]" = ()) -> set[str]:
        """Show the result (selected, keyframes hidden, frame range) and say what was made where;
        ``notes`` (faces reoriented, loose vertices ignored, ...) come as warnings."""
        shown = result_view.present(context.scene, context.view_layer, _settings(context), obj)
        self._hints(context, notes)
        took = f" in {seconds:.1f} s" if seconds is not None else ""
        where = ", ".join(f"'{c.name}'" for c in obj.users_collection)
        for line in obj.get("kfi_report_details", "").splitlines():  # the info log keeps them
            self.report({"INFO"}, f"Bake figures: {line}.")
        self.report({"INFO"}, f"Baked '{obj.name}'{took} into collection {where}; "  # the report
                              + "; ".join(shown) + ". " + obj.get("kfi_report", ""))  # has frames
        return {"FINISHED"}

    def cancel(self, context: bpy.types.Context) -> None:

        """Blender ends the operator (window closed, file loaded) while it runs: stop the job
        and take out what was written."""
        if self._job is not None:
            self._job.cancel()
        if self._writer is not None:
            self._writer.close()
        self._finish(context)


class KFI_OT_export_farm_job(bpy.types.Operator):
    """Write this bake as a render-farm job beside the saved .blend: an Open Job Description job template (openjd run, AWS Deadline Cloud) whose tasks are the bake's stages"""

    bl_idname = "keyframe_implicit.export_farm_job"
    bl_label = "Export Farm Job"
    bl_options = set()  # writes files only: no undo step, the scene is unchanged

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        """Only a setup the Bake button accepts, in a saved file: the job is written beside
        it and bakes a copy of it."""
        if not bpy.data.filepath:
            cls.poll_message_set("Save the .blend first: the job is written beside it.")
            return False
        return KFI_OT_bake.poll(context)

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            job_dir = farm.export_job(context.scene, context.evaluated_depsgraph_get(),
                                      bpy.data.filepath, bpy.app.binary_path,
                                      cache=work_cache.directory())
        except (ValueError, OSError) as exc:
            self.report({"ERROR"}, _failed("Export Farm Job failed", str(exc)))
            return {"CANCELLED"}
        if bpy.data.is_dirty:
            self.report({"WARNING"}, "The file has changes that are not saved: the job bakes the "
                                     "file as it was saved. Save and export again to include them.")
        self.report({"INFO"}, f"Farm job written to {job_dir}. Run it here with 'openjd run "
                              f"{os.path.join(job_dir, 'template.yaml')}', or send it to AWS "
                              f"Deadline Cloud with 'deadline bundle submit {job_dir}'.")
        return {"FINISHED"}


class KFI_OT_clear_cache(bpy.types.Operator):
    """Forget the distance fields and maps kept for the next bake and the live preview: the next bake computes everything again"""

    bl_idname = "keyframe_implicit.clear_cache"
    bl_label = "Clear Cache"
    bl_options = set()  # files and the preview's memory only: no undo step

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            freed = work_cache.clear()
        except OSError as exc:
            self.report({"ERROR"}, f"Clear Cache failed: {exc}")
            return {"CANCELLED"}
        preview.clear_cache()
        self.report({"INFO"}, f"Cache cleared: {freed / 2**20:,.1f} MB freed in "
                              f"{work_cache.directory()}.")
        return {"FINISHED"}


classes = (
    KFI_OT_add_keyframe,
    KFI_OT_remove_keyframe,
    KFI_OT_move_keyframe,
    KFI_OT_add_feature_pair,
    KFI_OT_pair_selected,
    KFI_OT_remove_feature_pair,
    KFI_OT_select_pair,
    KFI_OT_snap_features,
    KFI_OT_bake,
    KFI_OT_export_farm_job,
    KFI_OT_clear_cache,
    KFI_MT_menu,
)
