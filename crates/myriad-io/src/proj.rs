//! Coordinate reference systems through PROJ (<https://proj.org>): the library pyproj, GDAL, PDAL
//! and QGIS use, so a point moves here exactly as it moves there.
//!
//! PROJ is loaded when a command first needs it (`libproj.so.25`, Debian's `libproj25`; or the
//! file `MYRIAD_LIBPROJ` names), not linked: Myriad builds and runs on a machine without it, and
//! only the commands that change or name coordinate systems ask for it, with a one-line error
//! saying what to install. The `proj` crate links PROJ at build time (its release for Debian's
//! PROJ 9.1 also transforms only x and y); the two dozen functions used here are declared below.
//!
//! PROJ's objects belong to one context, which one thread uses at a time: a [`Transform`] or
//! [`Crs`] is `Send`, not `Sync`; each thread makes its own.

use std::ffi::{CStr, CString, c_char, c_int, c_void};
use std::sync::OnceLock;

type Ctx = c_void;
type Pj = c_void;
type Str = *const c_char;

/// The functions of PROJ's C API used here (proj.h, PROJ 8 and later).
struct Api {
    #[cfg(not(target_arch = "wasm32"))]
    _lib: libloading::Library,
    context_create: unsafe extern "C" fn() -> *mut Ctx,
    context_destroy: unsafe extern "C" fn(*mut Ctx) -> *mut Ctx,
    context_set_enable_network: unsafe extern "C" fn(*mut Ctx, c_int) -> c_int,
    context_errno: unsafe extern "C" fn(*mut Ctx) -> c_int,
    context_errno_string: unsafe extern "C" fn(*mut Ctx, c_int) -> Str,
    log_level: unsafe extern "C" fn(*mut Ctx, c_int) -> c_int,
    create: unsafe extern "C" fn(*mut Ctx, Str) -> *mut Pj,
    create_crs_to_crs_from_pj:
        unsafe extern "C" fn(*mut Ctx, *const Pj, *const Pj, *mut c_void, *const Str) -> *mut Pj,
    normalize_for_visualization: unsafe extern "C" fn(*mut Ctx, *const Pj) -> *mut Pj,
    destroy: unsafe extern "C" fn(*mut Pj) -> *mut Pj,
    #[allow(clippy::type_complexity)]
    trans_generic: unsafe extern "C" fn(
        *mut Pj,
        c_int,
        *mut f64,
        usize,
        usize,
        *mut f64,
        usize,
        usize,
        *mut f64,
        usize,
        usize,
        *mut f64,
        usize,
        usize,
    ) -> usize,
    errno_reset: unsafe extern "C" fn(*const Pj) -> c_int,
    get_type: unsafe extern "C" fn(*const Pj) -> c_int,
    get_name: unsafe extern "C" fn(*const Pj) -> Str,
    get_id_auth_name: unsafe extern "C" fn(*const Pj, c_int) -> Str,
    get_id_code: unsafe extern "C" fn(*const Pj, c_int) -> Str,
    get_source_crs: unsafe extern "C" fn(*mut Ctx, *const Pj) -> *mut Pj,
    as_wkt: unsafe extern "C" fn(*mut Ctx, *const Pj, c_int, *const Str) -> Str,
    as_proj_string: unsafe extern "C" fn(*mut Ctx, *const Pj, c_int, *const Str) -> Str,
    crs_get_sub_crs: unsafe extern "C" fn(*mut Ctx, *const Pj, c_int) -> *mut Pj,
    crs_get_coordinate_system: unsafe extern "C" fn(*mut Ctx, *const Pj) -> *mut Pj,
    cs_get_axis_count: unsafe extern "C" fn(*mut Ctx, *const Pj) -> c_int,
    #[allow(clippy::type_complexity)]
    cs_get_axis_info: unsafe extern "C" fn(
        *mut Ctx,
        *const Pj,
        c_int,
        *mut Str,
        *mut Str,
        *mut Str,
        *mut f64,
        *mut Str,
        *mut Str,
        *mut Str,
    ) -> c_int,
    create_compound_crs: unsafe extern "C" fn(*mut Ctx, Str, *mut Pj, *mut Pj) -> *mut Pj,
    get_ellipsoid: unsafe extern "C" fn(*mut Ctx, *const Pj) -> *mut Pj,
    ellipsoid_get_parameters: unsafe extern "C" fn(
        *mut Ctx,
        *const Pj,
        *mut f64,
        *mut f64,
        *mut c_int,
        *mut f64,
    ) -> c_int,
}

/// What to install when PROJ is missing.
pub const MISSING: &str = "PROJ's library was not found (install Debian's libproj25 and proj-data, \
or name libproj.so in MYRIAD_LIBPROJ)";

fn api() -> Result<&'static Api, String> {
    static API: OnceLock<Result<Api, String>> = OnceLock::new();
    API.get_or_init(load).as_ref().map_err(Clone::clone)
}

/// Whether PROJ can be loaded here (tests that need it skip without).
pub fn available() -> bool {
    api().is_ok()
}

/// No PROJ in the browser (the web viewer's WebAssembly reads points, never reprojects them).
#[cfg(target_arch = "wasm32")]
fn load() -> Result<Api, String> {
    Err(MISSING.to_string())
}

#[cfg(not(target_arch = "wasm32"))]
fn load() -> Result<Api, String> {
    let names: Vec<String> = match std::env::var("MYRIAD_LIBPROJ") {
        Ok(p) if !p.is_empty() => vec![p],
        _ => [
            "libproj.so.25",
            "libproj.so",
            "libproj.dylib",
            "libproj.so.22",
        ]
        .map(String::from)
        .to_vec(),
    };
    let mut why = String::new();
    let lib = names
        .iter()
        // SAFETY: loading PROJ runs its initialisers, which only set up its own state (no
        // callbacks into this process, no global state of ours touched); the library is kept
        // loaded for the rest of the process, in `Api`, so nothing it gave out dangles.
        .find_map(|n| match unsafe { libloading::Library::new(n) } {
            Ok(l) => Some(l),
            Err(e) => {
                why = e.to_string();
                None
            }
        })
        .ok_or_else(|| match std::env::var("MYRIAD_LIBPROJ") {
            Ok(p) if !p.is_empty() => format!("MYRIAD_LIBPROJ={p}: {why}"),
            _ => MISSING.to_string(),
        })?;
    macro_rules! f {
        ($name:literal) => {{
            // SAFETY: the symbol is PROJ's function of that name, with the signature proj.h
            // gives it; the library stays loaded as long as `Api` (for the whole process).
            let s = unsafe { lib.get(concat!($name, "\0").as_bytes()) }
                .map_err(|_| format!("{MISSING}: this PROJ lacks {}", $name))?;
            *s
        }};
    }
    Ok(Api {
        context_create: f!("proj_context_create"),
        context_destroy: f!("proj_context_destroy"),
        context_set_enable_network: f!("proj_context_set_enable_network"),
        context_errno: f!("proj_context_errno"),
        context_errno_string: f!("proj_context_errno_string"),
        log_level: f!("proj_log_level"),
        create: f!("proj_create"),
        create_crs_to_crs_from_pj: f!("proj_create_crs_to_crs_from_pj"),
        normalize_for_visualization: f!("proj_normalize_for_visualization"),
        destroy: f!("proj_destroy"),
        trans_generic: f!("proj_trans_generic"),
        errno_reset: f!("proj_errno_reset"),
        get_type: f!("proj_get_type"),
        get_name: f!("proj_get_name"),
        get_id_auth_name: f!("proj_get_id_auth_name"),
        get_id_code: f!("proj_get_id_code"),
        get_source_crs: f!("proj_get_source_crs"),
        as_wkt: f!("proj_as_wkt"),
        as_proj_string: f!("proj_as_proj_string"),
        crs_get_sub_crs: f!("proj_crs_get_sub_crs"),
        crs_get_coordinate_system: f!("proj_crs_get_coordinate_system"),
        cs_get_axis_count: f!("proj_cs_get_axis_count"),
        cs_get_axis_info: f!("proj_cs_get_axis_info"),
        create_compound_crs: f!("proj_create_compound_crs"),
        get_ellipsoid: f!("proj_get_ellipsoid"),
        ellipsoid_get_parameters: f!("proj_ellipsoid_get_parameters"),
        _lib: lib,
    })
}

/// A PROJ context: its own database connection and error state.
struct Context {
    api: &'static Api,
    ptr: *mut Ctx,
}

impl Context {
    fn new() -> Result<Context, String> {
        let api = api()?;
        // SAFETY: plain constructor; the pointer is destroyed once, in Drop.
        let ptr = unsafe { (api.context_create)() };
        if ptr.is_null() {
            return Err("PROJ could not make a context".into());
        }
        // Quiet (PROJ logs errors to stderr itself) and offline: a transform uses the grids
        // installed, never a download in the middle of a build.
        // SAFETY: `ptr` is the non-null context just made, not yet shared with anything or
        // any thread; both setters take a context and plain integers and keep no pointer.
        unsafe {
            (api.log_level)(ptr, 0);
            (api.context_set_enable_network)(ptr, 0);
        }
        Ok(Context { api, ptr })
    }

    fn error(&self) -> String {
        // SAFETY: the context is alive; PROJ returns a static or context-owned string.
        unsafe {
            let e = (self.api.context_errno)(self.ptr);
            text((self.api.context_errno_string)(self.ptr, e))
                .unwrap_or_else(|| format!("error {e}"))
        }
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        // SAFETY: every object of this context was destroyed first (they hold an Rc to it).
        unsafe { (self.api.context_destroy)(self.ptr) };
    }
}

/// A string PROJ returned (owned by PROJ), copied.
///
/// # Safety
/// `s` is null or a NUL-terminated string that PROJ keeps valid during this call (callers pass
/// what PROJ just returned, before any other call on the object or context that owns it).
unsafe fn text(s: Str) -> Option<String> {
    // SAFETY: `s` is not null here, and by this function's contract points to a NUL-terminated
    // string valid while it is copied.
    (!s.is_null()).then(|| unsafe { CStr::from_ptr(s) }.to_string_lossy().into_owned())
}

/// An object of PROJ (a CRS, a coordinate system, an operation), destroyed with it.
struct Object {
    ctx: std::rc::Rc<Context>,
    ptr: *mut Pj,
}

impl Object {
    fn wrap(ctx: &std::rc::Rc<Context>, ptr: *mut Pj, what: &str) -> Result<Object, String> {
        if ptr.is_null() {
            return Err(format!("{what}: {}", ctx.error()));
        }
        Ok(Object {
            ctx: ctx.clone(),
            ptr,
        })
    }
    fn api(&self) -> &'static Api {
        self.ctx.api
    }
    fn kind(&self) -> c_int {
        // SAFETY: `self.ptr` is a non-null PJ (checked in `wrap`) not yet destroyed (only Drop
        // does that), used by the one thread that holds this value (Object is not Sync).
        unsafe { (self.api().get_type)(self.ptr) }
    }
    fn name(&self) -> Option<String> {
        // SAFETY: a live PJ as in `kind`; the name PROJ returns (or null) belongs to the object,
        // which outlives this call, and `text` copies it before anything else touches it.
        unsafe { text((self.api().get_name)(self.ptr)) }
    }
    fn derived(&self, ptr: *mut Pj, what: &str) -> Result<Object, String> {
        Object::wrap(&self.ctx, ptr, what)
    }
}

impl Drop for Object {
    fn drop(&mut self) {
        // SAFETY: made by PROJ in this context, destroyed once.
        unsafe { (self.api().destroy)(self.ptr) };
    }
}

// PJ_TYPE values (proj.h).
const GEOCENTRIC: c_int = 10;
const GEOGRAPHIC_2D: c_int = 12;
const GEOGRAPHIC_3D: c_int = 13;
const PROJECTED: c_int = 15;
const COMPOUND: c_int = 16;
const BOUND: c_int = 19;
/// GEODETIC_CRS to OTHER_CRS: the types of CRSs.
const CRS_TYPES: std::ops::RangeInclusive<c_int> = 9..=20;
// PJ_WKT_TYPE and PJ_PROJ_STRING_TYPE values.
const WKT2_2019: c_int = 2;
const WKT1_GDAL: c_int = 4;
const PROJ_4: c_int = 1;
const FORWARD: c_int = 1;

/// What kind of coordinates a CRS gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Easting and northing on a map projection.
    Projected,
    /// Longitude and latitude (in Myriad's x, y order), with or without an ellipsoidal height.
    Geographic,
    /// Earth-centred, earth-fixed X, Y, Z.
    Geocentric,
    /// Anything else PROJ knows (engineering, ...).
    Other,
}

/// A coordinate reference system PROJ understands: `EPSG:n`, `EPSG:h+v`, WKT (1 or 2), a PROJ
/// string or PROJJSON.
pub struct Crs {
    obj: Object,
    /// A bound CRS's source (the CRS without its TOWGS84 hint), as PROJ's inspection needs.
    source: Option<Object>,
}

// SAFETY: the context and its objects move between threads only together (the Rc is never
// cloned out of the value that owns it) and are used by one thread at a time (not Sync).
unsafe impl Send for Crs {}

impl Crs {
    /// The CRS `definition` names. Errors are one line: PROJ's reason.
    pub fn new(definition: &str) -> Result<Crs, String> {
        let ctx = std::rc::Rc::new(Context::new()?);
        Crs::in_context(&ctx, definition)
    }

    fn in_context(ctx: &std::rc::Rc<Context>, definition: &str) -> Result<Crs, String> {
        let def = definition.trim();
        let c =
            CString::new(def).map_err(|_| "a coordinate system has no NUL bytes".to_string())?;
        let obj = Object::wrap(
            ctx,
            // SAFETY: `ctx.ptr` is a live context (the Rc keeps it until its objects are gone);
            // `c` is NUL-terminated and lives past the call, which copies what it needs. The new
            // PJ (or null) is owned by `wrap`, which destroys it once.
            unsafe { (ctx.api.create)(ctx.ptr, c.as_ptr()) },
            &short(def),
        )?;
        Crs::of(obj).ok_or_else(|| format!("{}: not a coordinate reference system", short(def)))
    }

    /// `obj` as a CRS (None where it is another kind of object: an operation, a datum).
    fn of(obj: Object) -> Option<Crs> {
        if !(CRS_TYPES).contains(&obj.kind()) {
            return None;
        }
        let source = (obj.kind() == BOUND)
            .then(|| {
                // SAFETY: `obj` is a live PJ of the live context `obj.ctx`; PROJ returns a new
                // object (or null), owned from here on by `derived` and destroyed once.
                let p = unsafe { (obj.api().get_source_crs)(obj.ctx.ptr, obj.ptr) };
                obj.derived(p, "the bound CRS's source").ok()
            })
            .flatten();
        Some(Crs { obj, source })
    }

    /// The CRS itself (a bound CRS's source).
    fn core(&self) -> &Object {
        self.source.as_ref().unwrap_or(&self.obj)
    }

    /// The horizontal (or geocentric) part's kind.
    pub fn horizontal_kind(&self) -> Kind {
        let o = self.core();
        let k = if o.kind() == COMPOUND {
            // SAFETY: `o` is a live compound CRS of its live context; the part PROJ returns for
            // index 0 (or null) is a new object owned by `derived`, destroyed once.
            let p = unsafe { (o.api().crs_get_sub_crs)(o.ctx.ptr, o.ptr, 0) };
            match o.derived(p, "horizontal part") {
                Ok(h) => h.kind(),
                Err(_) => return Kind::Other,
            }
        } else {
            o.kind()
        };
        match k {
            PROJECTED => Kind::Projected,
            GEOGRAPHIC_2D | GEOGRAPHIC_3D => Kind::Geographic,
            GEOCENTRIC => Kind::Geocentric,
            _ => Kind::Other,
        }
    }

    /// Whether the CRS has a vertical part of its own (a compound CRS).
    pub fn is_compound(&self) -> bool {
        self.core().kind() == COMPOUND
    }

    pub fn name(&self) -> String {
        self.obj.name().unwrap_or_else(|| "unnamed".into())
    }

    /// "EPSG:n" where the definition carries that identifier.
    pub fn code(&self) -> Option<String> {
        let o = &self.obj;
        // SAFETY: `o` is a live PJ; the identifier strings (or null) belong to it, outlive
        // these calls, and `text` copies each before the next call.
        let auth = unsafe { text((o.api().get_id_auth_name)(o.ptr, 0)) }?;
        // SAFETY: as above.
        let code = unsafe { text((o.api().get_id_code)(o.ptr, 0)) }?;
        Some(format!("{auth}:{code}"))
    }

    /// OGC WKT 1 as GDAL writes it (what LAS 1.4 and COPC readers expect), else WKT2:2019.
    pub fn wkt(&self) -> Result<String, String> {
        let o = &self.obj;
        let one_line = c"MULTILINE=NO";
        let options = [one_line.as_ptr(), std::ptr::null()];
        for kind in [WKT1_GDAL, WKT2_2019] {
            // SAFETY: live context and PJ; `options` is a null-terminated list of pointers to a
            // 'static NUL-terminated literal, alive across the call. The WKT returned (or null)
            // belongs to `o` and stays valid until the next call on it.
            let s = unsafe { (o.api().as_wkt)(o.ctx.ptr, o.ptr, kind, options.as_ptr()) };
            // SAFETY: `s` is what PROJ just returned, still valid; copied at once.
            if let Some(t) = unsafe { text(s) } {
                return Ok(t);
            }
        }
        Err(format!("{}: PROJ cannot write it as WKT", self.name()))
    }

    /// The PROJ.4 string of the horizontal part (what proj4js, and Potree's map, read).
    pub fn proj4(&self) -> Result<String, String> {
        let o = &self.obj;
        // SAFETY: live context and PJ; null is PROJ's "no options". The string returned (or
        // null) belongs to `o` and stays valid until the next call on it.
        let s = unsafe { (o.api().as_proj_string)(o.ctx.ptr, o.ptr, PROJ_4, std::ptr::null()) };
        // SAFETY: `s` is what PROJ just returned, still valid; copied at once.
        let s = unsafe { text(s) }
            .ok_or_else(|| format!("{}: PROJ cannot write it as a PROJ string", self.name()))?;
        Ok(s.replace(" +type=crs", "").trim().to_string())
    }

    /// Each axis's unit in metres (linear) or radians (angular), and whether it is angular.
    pub fn axis_units(&self) -> Result<Vec<(f64, bool)>, String> {
        let mut units = Vec::new();
        let o = self.core();
        let parts: Vec<Object> = if o.kind() == COMPOUND {
            (0..2)
                .map(|i| {
                    // SAFETY: `o` is a live compound CRS of its live context; each part PROJ
                    // returns (or null) is a new object owned by `derived`, destroyed once.
                    let p = unsafe { (o.api().crs_get_sub_crs)(o.ctx.ptr, o.ptr, i) };
                    o.derived(p, "part of a compound CRS")
                })
                .collect::<Result<_, _>>()?
        } else {
            Vec::new()
        };
        let list: Vec<&Object> = if parts.is_empty() {
            vec![o]
        } else {
            parts.iter().collect()
        };
        for part in list {
            // SAFETY: `part` is a live CRS of its live context; the coordinate system returned
            // (or null) is a new object owned by `derived`, destroyed once.
            let cs = unsafe { (part.api().crs_get_coordinate_system)(part.ctx.ptr, part.ptr) };
            let cs = part.derived(cs, "coordinate system")?;
            // SAFETY: `cs` is a live, non-null coordinate system of its live context.
            let n = unsafe { (cs.api().cs_get_axis_count)(cs.ctx.ptr, cs.ptr) };
            for i in 0..n.max(0) {
                let mut factor = 0.0;
                let mut unit: Str = std::ptr::null();
                let null = std::ptr::null_mut();
                // SAFETY: live context and coordinate system, `i` below its axis count; PROJ
                // writes only through the out-pointers that are not null (it allows null for
                // each), here `factor` and `unit`, locals that outlive the call. The unit name
                // belongs to `cs`, which lives to the end of this loop's body.
                let ok = unsafe {
                    (cs.api().cs_get_axis_info)(
                        cs.ctx.ptr,
                        cs.ptr,
                        i,
                        null,
                        null,
                        null,
                        &mut factor,
                        &mut unit,
                        null,
                        null,
                    )
                };
                if ok == 0 {
                    return Err(format!("{}: axis {i}: {}", self.name(), cs.ctx.error()));
                }
                // SAFETY: `unit` is null or the name PROJ just set, owned by the live `cs`.
                let name = unsafe { text(unit) }
                    .unwrap_or_default()
                    .to_ascii_lowercase();
                let angular =
                    name.contains("degree") || name.contains("radian") || name.contains("grad");
                units.push((factor, angular));
            }
        }
        Ok(units)
    }

    /// The ellipsoid's semi-major axis and inverse flattening (0 for a sphere).
    pub fn ellipsoid(&self) -> Result<(f64, f64), String> {
        let o = &self.obj;
        // SAFETY: live context and PJ; the ellipsoid returned (or null) is a new object owned
        // by `derived`, destroyed once.
        let e = unsafe { (o.api().get_ellipsoid)(o.ctx.ptr, o.ptr) };
        let e = o.derived(e, "ellipsoid")?;
        let (mut a, mut b, mut computed, mut inv_f) = (0.0, 0.0, 0, 0.0);
        // SAFETY: live context and ellipsoid; the four out-pointers are locals of the types
        // proj.h gives (double, double, int, double), alive across the call; PROJ keeps none.
        let ok = unsafe {
            (e.api().ellipsoid_get_parameters)(
                e.ctx.ptr,
                e.ptr,
                &mut a,
                &mut b,
                &mut computed,
                &mut inv_f,
            )
        };
        if ok == 0 {
            return Err(format!("{}: ellipsoid: {}", self.name(), e.ctx.error()));
        }
        Ok((a, inv_f))
    }
}

impl std::fmt::Debug for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Crs({})", self.name())
    }
}

/// A definition cut to what an error line shows.
fn short(def: &str) -> String {
    let one: String = def.split_whitespace().collect::<Vec<_>>().join(" ");
    if one.chars().count() > 60 {
        format!("{}...", one.chars().take(57).collect::<String>())
    } else {
        one
    }
}

/// Points moved from one CRS to another by the operation PROJ chooses for them (pyproj's
/// `Transformer.from_crs(..., always_xy=True)`): longitude before latitude, easting before
/// northing, whatever order the CRS's definition gives its axes.
pub struct Transform {
    op: Object,
    source: Crs,
    /// The target CRS (with the source's vertical part where it had none of its own).
    target: Crs,
}

// SAFETY: as for Crs: moved with its context, used by one thread at a time.
unsafe impl Send for Transform {}

impl Transform {
    /// From `from` to `to`. When the source has a vertical part and the target is a horizontal
    /// CRS only (projected or 2D geographic), the target keeps the source's vertical part:
    /// heights stay the heights they were.
    pub fn new(from: &str, to: &str) -> Result<Transform, String> {
        let ctx = std::rc::Rc::new(Context::new()?);
        let source = Crs::in_context(&ctx, from)?;
        let mut target = Crs::in_context(&ctx, to)?;
        if source.is_compound() && matches!(target.core().kind(), PROJECTED | GEOGRAPHIC_2D) {
            let s = source.core();
            // SAFETY: `s` is a live compound CRS made in `ctx`, which is alive; the vertical
            // part returned (or null) is a new object owned by `derived`, destroyed once.
            let v = unsafe { (ctx.api.crs_get_sub_crs)(ctx.ptr, s.ptr, 1) };
            let v = s.derived(v, "the vertical part")?;
            let name = CString::new(format!(
                "{} + {}",
                target.name(),
                v.name().unwrap_or_default()
            ))
            .unwrap_or_default();
            // SAFETY: live context; `name` is NUL-terminated and outlives the call; both parts
            // are live PJs of this context that PROJ only reads (the compound keeps references
            // of its own, so destroying `target` and `v` afterwards is sound). The compound
            // returned (or null) is owned by `wrap`, destroyed once.
            let c = unsafe {
                (ctx.api.create_compound_crs)(ctx.ptr, name.as_ptr(), target.obj.ptr, v.ptr)
            };
            target = Crs {
                obj: Object::wrap(&ctx, c, "the compound target")?,
                source: None,
            };
        }
        // SAFETY: live context; source and target are live CRSs of it, only read; null area
        // and null options are PROJ's defaults. The operation returned (or null) is owned by
        // `wrap`, destroyed once.
        let op = unsafe {
            (ctx.api.create_crs_to_crs_from_pj)(
                ctx.ptr,
                source.obj.ptr,
                target.obj.ptr,
                std::ptr::null_mut(),
                std::ptr::null(),
            )
        };
        let op = Object::wrap(
            &ctx,
            op,
            &format!("from {} to {}", source.name(), target.name()),
        )?;
        // SAFETY: live context and operation (only read); the normalised operation returned
        // (or null) is a new object owned by `wrap`, destroyed once; `op` is destroyed apart.
        let norm = unsafe { (ctx.api.normalize_for_visualization)(ctx.ptr, op.ptr) };
        let op = Object::wrap(&ctx, norm, "the transformation's axis order")?;
        Ok(Transform { op, source, target })
    }

    pub fn source(&self) -> &Crs {
        &self.source
    }

    pub fn target(&self) -> &Crs {
        &self.target
    }

    /// Moves `points` in place; returns how many did not transform, which are set to NaN.
    pub fn apply(&mut self, points: &mut [[f64; 3]]) -> usize {
        if points.is_empty() {
            return 0;
        }
        let n = points.len();
        let stride = std::mem::size_of::<[f64; 3]>();
        let base = points.as_mut_ptr() as *mut f64;
        // SAFETY: `self.op` is a live operation used by this thread alone (`&mut self`). The
        // three strided views (x, y, z of each [f64; 3], `stride` bytes apart, n each) lie inside
        // `points`, borrowed mutably for the call; the null fourth view is PROJ's "no time".
        // PROJ writes the results in place and keeps no pointer.
        unsafe {
            (self.op.api().errno_reset)(self.op.ptr);
            (self.op.api().trans_generic)(
                self.op.ptr,
                FORWARD,
                base,
                stride,
                n,
                base.add(1),
                stride,
                n,
                base.add(2),
                stride,
                n,
                std::ptr::null_mut(),
                0,
                0,
            );
        }
        let mut failed = 0;
        for p in points.iter_mut() {
            if !p.iter().all(|c| c.is_finite()) {
                *p = [f64::NAN; 3];
                failed += 1;
            }
        }
        failed
    }

    /// One point moved (None where it does not transform).
    pub fn point(&mut self, p: [f64; 3]) -> Option<[f64; 3]> {
        let mut a = [p];
        (self.apply(&mut a) == 0).then_some(a[0])
    }
}

/// One [`Transform`] per worker thread (PROJ moves 0.3-0.5 M points/s on one core): points
/// moved on all cores.
pub struct Pool {
    workers: Vec<std::sync::Mutex<Transform>>,
}

impl Pool {
    pub fn new(from: &str, to: &str) -> Result<Pool, String> {
        let workers = (0..rayon::current_num_threads().clamp(1, 16))
            .map(|_| Transform::new(from, to).map(std::sync::Mutex::new))
            .collect::<Result<_, _>>()?;
        Ok(Pool { workers })
    }

    /// The calling thread's transform (one of the pool's, by rayon's thread index).
    pub fn get(&self) -> std::sync::MutexGuard<'_, Transform> {
        let i = rayon::current_thread_index().unwrap_or(0) % self.workers.len();
        self.workers[i].lock().unwrap_or_else(|e| e.into_inner())
    }

    /// `points` moved in place, split over all workers; how many did not transform (NaN).
    pub fn apply(&self, points: &mut [[f64; 3]]) -> usize {
        use rayon::prelude::*;
        let per = points.len().div_ceil(self.workers.len()).max(4096);
        points
            .par_chunks_mut(per)
            .map(|c| self.get().apply(c))
            .sum()
    }
}

/// Longitude, latitude (degrees) and ellipsoidal height (metres, on WGS 84) of points in `crs`,
/// as both viewers show a picked point.
pub struct Geographic {
    t: Transform,
}

impl Geographic {
    pub fn new(crs: &str) -> Result<Geographic, String> {
        Ok(Geographic {
            t: Transform::new(crs, "EPSG:4979")?,
        })
    }

    pub fn of(&mut self, p: [f64; 3]) -> Option<[f64; 3]> {
        self.t.point(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn skip() -> bool {
        if !available() {
            eprintln!("SKIPPED: {MISSING}");
            return true;
        }
        false
    }

    #[test]
    fn utm_and_back_and_what_a_crs_is() {
        if skip() {
            return;
        }
        let mut t = Transform::new("EPSG:4326", "EPSG:32610").unwrap();
        // Longitude first whatever EPSG:4326's axis order: the central meridian of zone 10.
        let p = t.point([-123.0, 44.0, 10.0]).unwrap();
        assert!((p[0] - 500_000.0).abs() < 1e-6, "{p:?}");
        assert!((p[1] - 4_871_873.4).abs() < 1.0, "{p:?}");
        assert_eq!(p[2], 10.0);
        let mut back = Transform::new("EPSG:32610", "EPSG:4326").unwrap();
        let q = back.point(p).unwrap();
        assert!(
            (q[0] + 123.0).abs() < 1e-12 && (q[1] - 44.0).abs() < 1e-12,
            "{q:?}"
        );

        let utm = Crs::new("EPSG:32610").unwrap();
        assert_eq!(utm.horizontal_kind(), Kind::Projected);
        assert_eq!(utm.code().as_deref(), Some("EPSG:32610"));
        assert!(
            utm.wkt()
                .unwrap()
                .starts_with("PROJCS[\"WGS 84 / UTM zone 10N\"")
        );
        assert!(
            utm.proj4().unwrap().contains("+proj=utm +zone=10"),
            "{}",
            utm.proj4().unwrap()
        );
        assert_eq!(utm.axis_units().unwrap(), vec![(1.0, false), (1.0, false)]);
        let ft = Crs::new("EPSG:2992").unwrap();
        assert!((ft.axis_units().unwrap()[0].0 - 0.3048).abs() < 1e-9);
        assert_eq!(
            Crs::new("EPSG:4978").unwrap().horizontal_kind(),
            Kind::Geocentric
        );
        let geo = Crs::new("EPSG:4326").unwrap();
        assert_eq!(geo.horizontal_kind(), Kind::Geographic);
        assert!(geo.axis_units().unwrap()[0].1);
        let c = Crs::new("EPSG:25832+5941").unwrap();
        assert!(c.is_compound());
        assert_eq!(c.axis_units().unwrap().len(), 3);
        assert!(
            Crs::new("EPSG:99999999")
                .unwrap_err()
                .contains("EPSG:99999999")
        );
        assert!(Crs::new("not a crs at all").is_err());
    }

    #[test]
    fn a_horizontal_target_keeps_the_vertical_part_and_failures_are_counted() {
        if skip() {
            return;
        }
        let mut t = Transform::new("EPSG:25832+5941", "EPSG:25833").unwrap();
        assert!(t.target().is_compound(), "{}", t.target().name());
        let p = t.point([500_000.0, 6_600_000.0, 123.25]).unwrap();
        assert_eq!(p[2], 123.25);
        // A latitude beyond the pole does not transform: counted, set to NaN, never 0,0.
        let mut g = Transform::new("EPSG:4326", "EPSG:32610").unwrap();
        let mut pts = [[-123.0, 44.0, 0.0], [-123.0, 95.0, 0.0]];
        assert_eq!(g.apply(&mut pts), 1);
        assert!(pts[1][0].is_nan() && pts[0][0].is_finite());
    }
}
