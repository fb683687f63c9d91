//! Contacts and collisions on rapier3d: static colliders for the town, swept kinematic actors.
//!
//! The town's static geometry is a rapier [`PhysicsWorld`] of fixed
//! colliders: buildings (convex hulls of their footprints, extruded), traffic
//! light poles (capsules), and the trees and street lamps beside the road
//! ([`Physics::add_props`]). Kerbs are not walls: a car's wheels climb them
//! (`crate::agents::kerb`), as in CARLA. Vehicles and pedestrians are kinematic, position-based
//! bodies (parry shapes kept here, not in the rapier world): their behaviour
//! (the bicycle model, the walker) proposes a new pose each 40 Hz tick and
//! [`Physics::move_actor`] realises as much of it as the world allows:
//!
//! 1. the new heading is taken if the turned shape at the old position
//!    touches nothing;
//! 2. the translation is swept (rapier's shape cast against the fixed
//!    colliders, parry's `cast_shapes` against the other actors at their
//!    current poses) and stops at the first contact, `SKIN_M` short of it;
//! 3. the rest of the motion slides along the contact (its component into the
//!    obstacle is dropped) and is swept again once.
//!
//! Actors move one after another in a fixed order, each against the others'
//! already updated poses, so no actor ever ends a tick inside another body or
//! a static collider, and the same inputs give the same poses bit for bit.
//! Separating motion is never blocked, so a car that hit something can drive
//! away by steering. Every blocked sweep is a contact; [`Physics::end_tick`]
//! turns the tick's contacts into [`ContactEvent`]s that name both parties.
//! The rapier world ([`Physics::world`]) holds the static town only, stepped
//! once when colliders are added so its query pipeline sees them: every
//! query here asks it for fixed colliders, and the actors are tested against
//! each other directly. (Until stop 60 the actors were kinematic bodies in it
//! too, and rapier stepped every tick for queries nobody made: 16 % of a
//! 20-car soak's time on CARLA's Town06, by `perf`.)
//!
//! Pedestrians do not collide with pedestrians or the static world (they
//! walk on sidewalks and step off them at crossings); they do collide with
//! vehicles, both ways.

use crate::agents::actor::ActorKind;
use crate::map::props::{LAMP_HEIGHT_M, LAMP_POST_M, Prop, PropKind, TRUNK_M};
use crate::map::town::Town;
use glam::{Quat, Vec2, Vec3};
use rapier3d::parry::query::{ShapeCastOptions, cast_shapes, intersection_test};
use rapier3d::parry::shape::{Capsule, Cuboid, Shape};
use rapier3d::prelude::*;
use std::collections::BTreeMap;

/// The default simulation step (seconds): 40 Hz (docs/protocol.md §1). A run steps
/// by its scenario's `timing.tick_s` (see [`Physics::new`]).
pub const DT_S: f32 = 0.025;
/// Gap left between bodies when a sweep stops at a contact (metres).
pub const SKIN_M: f32 = 0.02;
/// Ground clearance of a vehicle's collision box (metres).
pub const VEHICLE_CLEARANCE_M: f32 = 0.02;
/// Radius of a pedestrian's capsule (metres).
pub const PEDESTRIAN_RADIUS_M: f32 = 0.3;
/// Height of a pedestrian (metres).
pub const PEDESTRIAN_HEIGHT_M: f32 = 1.8;

/// What a static collider is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum StaticKind {
    /// A building.
    Building,
    /// A pole: a traffic light's or a street lamp's.
    Pole,
    /// A tree's trunk.
    Tree,
}

impl StaticKind {
    /// What it is, in a word ("building", "pole", "tree").
    pub fn name(self) -> &'static str {
        match self {
            StaticKind::Building => "building",
            StaticKind::Pole => "pole",
            StaticKind::Tree => "tree",
        }
    }

    fn code(self) -> u128 {
        match self {
            StaticKind::Building => 1,
            StaticKind::Pole => 2,
            StaticKind::Tree => 3,
        }
    }

    fn from_code(c: u128) -> StaticKind {
        match c {
            2 => StaticKind::Pole,
            3 => StaticKind::Tree,
            _ => StaticKind::Building,
        }
    }
}

/// One side of a contact: an actor (by id and kind) or a piece of the static world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Party {
    /// A moving actor.
    Actor {
        /// The actor's id (the ego is 0).
        id: u32,
        /// Ego, vehicle or pedestrian.
        kind: ActorKind,
    },
    /// A static collider.
    Static(StaticKind),
}

impl Party {
    /// A key that orders parties: actors by id, then statics by kind.
    fn key(&self) -> (u8, u32) {
        match self {
            Party::Actor { id, .. } => (0, *id),
            Party::Static(k) => (1, k.code() as u32),
        }
    }
}

/// What an actor touched: the party, and the collider when it is static.
#[derive(Debug, Clone, Copy)]
struct Touch {
    party: Party,
    collider: Option<ColliderHandle>,
}

impl Touch {
    fn key(&self) -> (u8, u32) {
        match self.collider {
            Some(h) => (1, h.into_raw_parts().0),
            None => self.party.key(),
        }
    }
}

/// A contact found during a tick: `a` moved into `b`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContactEvent {
    /// The actor whose motion was blocked.
    pub a: Party,
    /// What it touched.
    pub b: Party,
    /// True when this pair was not in contact on the previous tick.
    pub started: bool,
}

/// What became of one requested move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveOutcome {
    /// Where the actor ended up (ground plane, metres).
    pub position: Vec2,
    /// Its heading (radians).
    pub yaw: f32,
    /// Distance realised along the requested motion over the distance requested (0..=1; 1 when no motion was asked).
    pub fraction: f32,
    /// What blocked the motion, if anything.
    pub hit: Option<Party>,
}

#[derive(Debug, Clone)]
struct Body {
    kind: ActorKind,
    shape: ShapeKind,
    centre_z: f32,
    ground_z: f32,
    position: Vec2,
    yaw: f32,
    radius: f32,
}

#[derive(Debug, Clone, Copy)]
enum ShapeKind {
    Box(Cuboid),
    Capsule(Capsule),
}

impl ShapeKind {
    fn shape(&self) -> &dyn Shape {
        match self {
            ShapeKind::Box(c) => c,
            ShapeKind::Capsule(c) => c,
        }
    }
}

fn pose(p: Vec2, z: f32, yaw: f32) -> Pose {
    Pose::from_parts(p.extend(z), Quat::from_rotation_z(yaw))
}

/// The rapier world plus the swept kinematic actors (see the module docs).
pub struct Physics {
    /// The rapier world: the town's fixed colliders (the actors are not in it).
    pub world: PhysicsWorld,
    bodies: Vec<Option<Body>>,
    contacts: BTreeMap<(u32, (u8, u32)), Touch>,
    prev_contacts: BTreeMap<(u32, (u8, u32)), Touch>,
    events: Vec<ContactEvent>,
}

impl Physics {
    /// A world with the town's static colliders (buildings, light poles) and no actors.
    pub fn new(town: &Town) -> Physics {
        let mut world = PhysicsWorld::new();
        let ground_z = town.ground_z();
        let fixed = |kind: StaticKind| kind.code();
        for b in &town.buildings {
            if b.footprint.len() < 3 || b.height_m.is_nan() || b.height_m <= 0.0 {
                continue;
            }
            let mut pts = Vec::with_capacity(b.footprint.len() * 2);
            for p in &b.footprint {
                pts.push(p.extend(ground_z - 1.0));
                pts.push(p.extend(ground_z + b.height_m));
            }
            if let Some(c) = ColliderBuilder::convex_hull(&pts) {
                world
                    .colliders
                    .insert(c.user_data(fixed(StaticKind::Building)));
            }
        }
        for l in &town.lights {
            let half = (l.head_height_m + 0.5) * 0.5;
            let c = ColliderBuilder::capsule_z(half, 0.15)
                .translation(l.position + Vec3::new(0.0, 0.0, half))
                .user_data(fixed(StaticKind::Pole));
            world.colliders.insert(c);
        }
        world.step();
        Physics {
            world,
            bodies: Vec::new(),
            contacts: BTreeMap::new(),
            prev_contacts: BTreeMap::new(),
            events: Vec::new(),
        }
    }

    /// Adds the trees' trunks and the street lamps' posts (`world::map::props`) as
    /// fixed colliders standing on `ground_z` (metres).
    pub fn add_props(&mut self, props: &[Prop], ground_z: f32) {
        for p in props {
            let (side, height, kind) = match p.kind {
                PropKind::Tree { crown_base_m, .. } => {
                    (TRUNK_M, crown_base_m + 0.5, StaticKind::Tree)
                }
                PropKind::StreetLamp => (LAMP_POST_M, LAMP_HEIGHT_M, StaticKind::Pole),
            };
            let c = ColliderBuilder::cuboid(side * 0.5, side * 0.5, height * 0.5)
                .position(pose(p.position, ground_z + height * 0.5, 0.0))
                .user_data(kind.code());
            self.world.colliders.insert(c);
        }
        self.world.step();
    }

    /// Adds a static box (street furniture, a parked obstacle): centre on the ground, size (metres), yaw (radians).
    pub fn add_static_box(
        &mut self,
        centre: Vec2,
        ground_z: f32,
        size: Vec3,
        yaw: f32,
        kind: StaticKind,
    ) {
        let half = size * 0.5;
        let c = ColliderBuilder::cuboid(half.x, half.y, half.z)
            .position(pose(centre, ground_z + half.z, yaw))
            .user_data(kind.code());
        self.world.colliders.insert(c);
        // Refresh the broad phase so queries see it at once.
        self.world.step();
    }

    fn new_body(&mut self, id: u32, body: Body) {
        let i = id as usize;
        if self.bodies.len() <= i {
            self.bodies.resize(i + 1, None);
        }
        self.bodies[i] = Some(body);
    }

    /// Adds (or replaces) a vehicle body: a box of `size` (length, width, height, metres) standing on `ground_z`.
    pub fn add_vehicle(
        &mut self,
        id: u32,
        kind: ActorKind,
        size: Vec3,
        position: Vec2,
        ground_z: f32,
        yaw: f32,
    ) {
        let half = size * 0.5;
        let centre_z = ground_z + VEHICLE_CLEARANCE_M + half.z;
        self.new_body(
            id,
            Body {
                kind,
                shape: ShapeKind::Box(Cuboid::new(half)),
                centre_z,
                ground_z,
                position,
                yaw,
                radius: half.truncate().length(),
            },
        );
    }

    /// Adds (or replaces) a pedestrian body: an upright capsule standing on `ground_z`.
    pub fn add_pedestrian(&mut self, id: u32, position: Vec2, ground_z: f32) {
        let half_h = PEDESTRIAN_HEIGHT_M * 0.5 - PEDESTRIAN_RADIUS_M;
        let centre_z = ground_z + PEDESTRIAN_HEIGHT_M * 0.5;
        self.new_body(
            id,
            Body {
                kind: ActorKind::Pedestrian,
                shape: ShapeKind::Capsule(Capsule::new_z(half_h, PEDESTRIAN_RADIUS_M)),
                centre_z,
                ground_z,
                position,
                yaw: 0.0,
                radius: PEDESTRIAN_RADIUS_M,
            },
        );
    }

    /// Removes an actor's body.
    pub fn remove(&mut self, id: u32) {
        if let Some(slot) = self.bodies.get_mut(id as usize) {
            *slot = None;
        }
    }

    /// Pose of an actor: (position, yaw) (metres, radians).
    pub fn pose_of(&self, id: u32) -> Option<(Vec2, f32)> {
        self.body(id).map(|b| (b.position, b.yaw))
    }

    fn body(&self, id: u32) -> Option<&Body> {
        self.bodies.get(id as usize).and_then(Option::as_ref)
    }

    fn collides(&self, mover: &Body, other: &Body) -> bool {
        let ped = |b: &Body| b.kind == ActorKind::Pedestrian;
        !(ped(mover) && ped(other))
    }

    /// Whether a vehicle box of `size` (metres) at a pose fits: it touches no static collider, and no actor (other than `ignore`) comes within `actor_margin_m` of it.
    pub fn vehicle_fits(
        &self,
        size: Vec3,
        position: Vec2,
        ground_z: f32,
        yaw: f32,
        actor_margin_m: f32,
        ignore: Option<u32>,
    ) -> bool {
        let half = size * 0.5;
        let shape = Cuboid::new(half);
        let pz = ground_z + VEHICLE_CLEARANCE_M + half.z;
        let ps = pose(position, pz, yaw);
        let qp = self
            .world
            .query_pipeline_with_filter(QueryFilter::only_fixed());
        if qp.intersect_shape(ps, &shape).next().is_some() {
            return false;
        }
        let r = half.truncate().length() + actor_margin_m;
        for (i, b) in self.bodies.iter().enumerate() {
            let Some(b) = b else { continue };
            if Some(i as u32) == ignore || (b.position - position).length() > r + b.radius {
                continue;
            }
            let pb = pose(b.position, b.centre_z, b.yaw);
            if rapier3d::parry::query::distance(&ps, &shape, &pb, b.shape.shape())
                .is_ok_and(|d| d.distance <= actor_margin_m)
            {
                return false;
            }
        }
        true
    }

    /// Whether a pedestrian at a spot would touch a vehicle or another pedestrian (within `margin_m`).
    pub fn pedestrian_fits(&self, position: Vec2, margin_m: f32) -> bool {
        self.bodies.iter().flatten().all(|b| {
            let d = (b.position - position).length();
            match b.shape {
                ShapeKind::Capsule(_) => d > 2.0 * PEDESTRIAN_RADIUS_M + margin_m,
                ShapeKind::Box(c) => {
                    // Distance to the box in its own frame.
                    let local = Vec2::from_angle(-b.yaw).rotate(position - b.position);
                    let q = local.abs() - c.half_extents.truncate();
                    q.max(Vec2::ZERO).length() > PEDESTRIAN_RADIUS_M + margin_m
                }
            }
        })
    }

    fn static_blocked(&self, b: &Body) -> bool {
        b.kind != ActorKind::Pedestrian
    }

    /// Intersection of actor `id`'s shape at a pose with anything it collides with.
    fn touches_at(&self, id: u32, b: &Body, p: Vec2, yaw: f32) -> bool {
        let ps = pose(p, b.centre_z, yaw);
        if self.static_blocked(b) {
            let qp = self
                .world
                .query_pipeline_with_filter(QueryFilter::only_fixed());
            if qp.intersect_shape(ps, b.shape.shape()).next().is_some() {
                return true;
            }
        }
        for (j, o) in self.bodies.iter().enumerate() {
            let Some(o) = o else { continue };
            if j as u32 == id
                || !self.collides(b, o)
                || (o.position - p).length() > b.radius + o.radius + SKIN_M
            {
                continue;
            }
            let po = pose(o.position, o.centre_z, o.yaw);
            if intersection_test(&ps, b.shape.shape(), &po, o.shape.shape())
                .is_ok_and(|h| h.intersecting)
            {
                return true;
            }
        }
        false
    }

    /// First contact of actor `id` swept from `p` by `motion` at heading `yaw`: (time of impact in 0..=1, world normal out of the mover, party).
    fn sweep(
        &self,
        id: u32,
        b: &Body,
        p: Vec2,
        yaw: f32,
        motion: Vec2,
    ) -> Option<(f32, Vec2, Touch)> {
        let ps = pose(p, b.centre_z, yaw);
        let vel = motion.extend(0.0);
        let opts = ShapeCastOptions {
            max_time_of_impact: 1.0,
            target_distance: SKIN_M,
            stop_at_penetration: false,
            compute_impact_geometry_on_penetration: true,
        };
        let mut best: Option<(f32, Vec2, Touch)> = None;
        if self.static_blocked(b) {
            let qp = self
                .world
                .query_pipeline_with_filter(QueryFilter::only_fixed());
            if let Some((h, hit)) = qp.cast_shape(&ps, vel, b.shape.shape(), opts) {
                let kind = self
                    .world
                    .colliders
                    .get(h)
                    .map_or(StaticKind::Building, |c| StaticKind::from_code(c.user_data));
                // normal1 is the hit collider's outward normal (world frame).
                let touch = Touch {
                    party: Party::Static(kind),
                    collider: Some(h),
                };
                best = Some((hit.time_of_impact, -hit.normal1.truncate(), touch));
            }
        }
        let reach = motion.length();
        for (j, o) in self.bodies.iter().enumerate() {
            let Some(o) = o else { continue };
            if j as u32 == id
                || !self.collides(b, o)
                || (o.position - p).length() > b.radius + o.radius + reach + SKIN_M
            {
                continue;
            }
            let po = pose(o.position, o.centre_z, o.yaw);
            if let Ok(Some(hit)) = cast_shapes(
                &ps,
                vel,
                b.shape.shape(),
                &po,
                Vec3::ZERO,
                o.shape.shape(),
                opts,
            ) && best.is_none_or(|(t, _, _)| hit.time_of_impact < t)
            {
                // normal1 is the mover's outward normal in its local frame.
                let n = (ps.rotation * hit.normal1).truncate();
                let touch = Touch {
                    party: Party::Actor {
                        id: j as u32,
                        kind: o.kind,
                    },
                    collider: None,
                };
                best = Some((hit.time_of_impact, n, touch));
            }
        }
        best
    }

    /// Moves actor `id` toward a pose as far as the world allows (see the module docs); records contacts.
    pub fn move_actor(&mut self, id: u32, target: Vec2, target_yaw: f32) -> MoveOutcome {
        let Some(b) = self.body(id).cloned() else {
            return MoveOutcome {
                position: target,
                yaw: target_yaw,
                fraction: 1.0,
                hit: None,
            };
        };
        let mut hit: Option<Touch> = None;
        let mut yaw = b.yaw;
        if target_yaw != b.yaw {
            if self.touches_at(id, &b, b.position, target_yaw)
                && !self.touches_at(id, &b, b.position, b.yaw)
            {
                hit = Some(self.blocker(id, &b, b.position, target_yaw));
            } else {
                yaw = target_yaw;
            }
        }
        let asked = target - b.position;
        let asked_len = asked.length();
        let mut p = b.position;
        let mut moved = 0.0f32;
        if asked_len > 0.0 {
            let mut motion = asked;
            for _ in 0..2 {
                if motion.length_squared() < 1e-12 {
                    break;
                }
                match self.sweep(id, &b, p, yaw, motion) {
                    None => {
                        p += motion;
                        moved += motion.length();
                        break;
                    }
                    Some((toi, n, touch)) => {
                        let step = motion * toi;
                        p += step;
                        moved += step.length();
                        hit = Some(touch);
                        let rest = motion - step;
                        let nn = n.normalize_or_zero();
                        motion = rest - nn * rest.dot(nn).max(0.0);
                    }
                }
            }
        }
        if let Some(t) = hit {
            self.contacts.insert((id, t.key()), t);
        }
        let body = self.bodies[id as usize].as_mut().expect("body exists");
        body.position = p;
        body.yaw = yaw;
        MoveOutcome {
            position: p,
            yaw,
            fraction: if asked_len > 0.0 {
                (moved / asked_len).min(1.0)
            } else {
                1.0
            },
            hit: hit.map(|t| t.party),
        }
    }

    fn blocker(&self, id: u32, b: &Body, p: Vec2, yaw: f32) -> Touch {
        let ps = pose(p, b.centre_z, yaw);
        for (j, o) in self.bodies.iter().enumerate() {
            let Some(o) = o else { continue };
            if j as u32 == id || !self.collides(b, o) {
                continue;
            }
            let po = pose(o.position, o.centre_z, o.yaw);
            if intersection_test(&ps, b.shape.shape(), &po, o.shape.shape())
                .is_ok_and(|h| h.intersecting)
            {
                let party = Party::Actor {
                    id: j as u32,
                    kind: o.kind,
                };
                return Touch {
                    party,
                    collider: None,
                };
            }
        }
        let qp = self
            .world
            .query_pipeline_with_filter(QueryFilter::only_fixed());
        let found = qp.intersect_shape(ps, b.shape.shape()).next();
        Touch {
            party: Party::Static(found.map_or(StaticKind::Building, |(_, c)| {
                StaticKind::from_code(c.user_data)
            })),
            collider: found.map(|(h, _)| h),
        }
    }

    /// Distance from actor `id` to what it touched (metres).
    fn touch_distance(&self, id: u32, t: &Touch) -> Option<f32> {
        match (t.collider, t.party) {
            (Some(h), _) => {
                let b = self.body(id)?;
                let c = self.world.colliders.get(h)?;
                let ps = pose(b.position, b.centre_z, b.yaw);
                rapier3d::parry::query::distance(&ps, b.shape.shape(), c.position(), c.shape())
                    .ok()
                    .map(|d| d.distance)
            }
            (None, Party::Actor { id: other, .. }) => self.distance(id, other),
            (None, Party::Static(_)) => None,
        }
    }

    /// Places an actor at a pose without sweeping (spawning, respawning); the caller checks it fits.
    pub fn teleport(&mut self, id: u32, position: Vec2, yaw: f32) {
        if let Some(b) = self.bodies.get_mut(id as usize).and_then(Option::as_mut) {
            b.position = position;
            b.yaw = yaw;
        }
    }

    /// Sets the ground height an actor stands on (metres), raising or lowering
    /// its body with it: a car on a bridge (CARLA's Town04, road 39, 10.7 m up)
    /// passes over the cars on the road below instead of meeting them.
    pub fn set_ground_z(&mut self, id: u32, ground_z: f32) {
        if let Some(b) = self.bodies.get_mut(id as usize).and_then(Option::as_mut)
            && b.ground_z != ground_z
        {
            b.centre_z += ground_z - b.ground_z;
            b.ground_z = ground_z;
        }
    }

    /// Ground height under an actor (metres).
    pub fn ground_z(&self, id: u32) -> Option<f32> {
        self.body(id).map(|b| b.ground_z)
    }

    /// Ends a tick: returns the tick's contact events.
    pub fn end_tick(&mut self) -> &[ContactEvent] {
        self.events.clear();
        for (&(id, key), t) in &self.contacts {
            let kind = self.body(id).map_or(ActorKind::Vehicle, |b| b.kind);
            self.events.push(ContactEvent {
                a: Party::Actor { id, kind },
                b: t.party,
                started: !self.prev_contacts.contains_key(&(id, key)),
            });
        }
        // A pair stays in contact while the two stay within two skins of each other,
        // even on ticks where neither pushed (so resting contact does not restart).
        let keep: Vec<_> = self
            .prev_contacts
            .iter()
            .filter(|(k, t)| {
                !self.contacts.contains_key(k)
                    && self
                        .touch_distance(k.0, t)
                        .is_some_and(|d| d <= 2.0 * SKIN_M)
            })
            .map(|(k, t)| (*k, *t))
            .collect();
        self.contacts.extend(keep);
        std::mem::swap(&mut self.prev_contacts, &mut self.contacts);
        self.contacts.clear();
        &self.events
    }

    /// Distance between two actors' shapes (metres; 0 when they touch or overlap).
    pub fn distance(&self, a: u32, b: u32) -> Option<f32> {
        let (x, y) = (self.body(a)?, self.body(b)?);
        let px = pose(x.position, x.centre_z, x.yaw);
        let py = pose(y.position, y.centre_z, y.yaw);
        rapier3d::parry::query::distance(&px, x.shape.shape(), &py, y.shape.shape())
            .ok()
            .map(|d| d.distance)
    }

    /// Whether two actors' shapes overlap (penetrate) right now.
    pub fn overlapping(&self, a: u32, b: u32) -> bool {
        self.distance(a, b).is_some_and(|d| d <= 0.0)
    }

    /// Distance from an actor's shape to the nearest static collider it collides with (metres; infinity when none is near).
    pub fn static_clearance(&self, id: u32) -> f32 {
        let Some(b) = self.body(id) else {
            return f32::INFINITY;
        };
        let ps = pose(b.position, b.centre_z, b.yaw);
        let qp = self
            .world
            .query_pipeline_with_filter(QueryFilter::only_fixed());
        let probe = Cuboid::new(Vec3::splat(b.radius + 5.0));
        let mut best = f32::INFINITY;
        for (_, c) in qp.intersect_shape(ps, &probe) {
            if let Ok(d) =
                rapier3d::parry::query::distance(&ps, b.shape.shape(), c.position(), c.shape())
            {
                best = best.min(d.distance);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::town::{Building, Town};

    fn walled_town() -> Town {
        // A single building whose west wall is the plane x = 20.
        Town {
            buildings: vec![Building {
                footprint: vec![
                    Vec2::new(20.0, -20.0),
                    Vec2::new(30.0, -20.0),
                    Vec2::new(30.0, 20.0),
                    Vec2::new(20.0, 20.0),
                ],
                height_m: 10.0,
            }],
            bounds: (Vec2::splat(-50.0), Vec2::splat(50.0)),
            ..Town::empty("wall")
        }
    }

    fn car() -> Vec3 {
        Vec3::new(4.79, 2.16, 1.45)
    }

    #[test]
    fn a_tree_beside_the_road_is_solid_and_named() {
        let mut ph = Physics::new(&Town::empty("props"));
        let tree = Prop {
            position: Vec2::new(10.0, 0.0),
            outward: Vec2::Y,
            kind: PropKind::Tree {
                crown_base_m: 2.5,
                crown_radius_m: 1.5,
            },
        };
        ph.add_props(&[tree], 0.0);
        ph.add_vehicle(0, ActorKind::Ego, car(), Vec2::new(0.0, 0.0), 0.0, 0.0);
        let mut hit = None;
        for _ in 0..80 {
            let (p, yaw) = ph.pose_of(0).unwrap();
            ph.move_actor(0, p + Vec2::new(0.25, 0.0), yaw);
            if let Some(ev) = ph.end_tick().iter().find(|e| e.started) {
                hit = Some(ev.b);
            }
        }
        assert_eq!(hit, Some(Party::Static(StaticKind::Tree)));
        let (p, _) = ph.pose_of(0).unwrap();
        assert!(
            p.x + 4.79 / 2.0 <= 10.0 - TRUNK_M / 2.0 + 1e-3,
            "stopped at the trunk: {p}"
        );
    }

    #[test]
    fn car_driven_into_a_wall_stops_without_penetrating() {
        let mut ph = Physics::new(&walled_town());
        ph.add_vehicle(0, ActorKind::Ego, car(), Vec2::new(0.0, 0.0), 0.0, 0.0);
        let mut hit_at = None;
        for t in 0..200 {
            let (p, yaw) = ph.pose_of(0).unwrap();
            let out = ph.move_actor(0, p + Vec2::new(0.25, 0.0), yaw);
            let ev = ph.end_tick().to_vec();
            if out.hit.is_some() && hit_at.is_none() {
                hit_at = Some(t);
                assert_eq!(ev.len(), 1);
                assert_eq!(
                    ev[0].a,
                    Party::Actor {
                        id: 0,
                        kind: ActorKind::Ego
                    }
                );
                assert_eq!(ev[0].b, Party::Static(StaticKind::Building));
                assert!(ev[0].started);
            }
        }
        assert!(hit_at.is_some());
        let (p, _) = ph.pose_of(0).unwrap();
        // Front bumper at x + 2.395, the wall at 20: stopped just short of it.
        let front = p.x + 4.79 / 2.0;
        assert!(front <= 20.0 && front > 20.0 - 0.05, "front at {front}");
        assert!(ph.static_clearance(0) >= 0.0);
        // Still in contact, not newly.
        let (p, yaw) = ph.pose_of(0).unwrap();
        ph.move_actor(0, p + Vec2::new(0.25, 0.0), yaw);
        assert!(!ph.end_tick()[0].started);
    }

    #[test]
    fn car_hitting_a_wall_at_an_angle_slides_and_can_steer_away() {
        let mut ph = Physics::new(&walled_town());
        let yaw0 = 0.5f32;
        ph.add_vehicle(0, ActorKind::Ego, car(), Vec2::new(14.0, 0.0), 0.0, yaw0);
        let mut hit = false;
        for _ in 0..40 {
            let (p, yaw) = ph.pose_of(0).unwrap();
            let out = ph.move_actor(0, p + Vec2::from_angle(yaw) * 0.2, yaw);
            hit |= out.hit.is_some();
            ph.end_tick();
        }
        assert!(hit);
        assert!(ph.static_clearance(0) >= 0.0);
        let (p0, _) = ph.pose_of(0).unwrap();
        // Steer away (turn left, toward -x side) while moving: yaw increases, car leaves the wall.
        for _ in 0..80 {
            let (p, yaw) = ph.pose_of(0).unwrap();
            let new_yaw = (yaw + 0.03).min(2.5);
            ph.move_actor(0, p + Vec2::from_angle(new_yaw) * 0.2, new_yaw);
            ph.end_tick();
        }
        let (p1, yaw1) = ph.pose_of(0).unwrap();
        assert!(yaw1 > 2.0, "yaw {yaw1}");
        assert!(p1.x < p0.x - 2.0, "did not drive away: {p0} -> {p1}");
        assert!(ph.static_clearance(0) > 0.5);
    }

    #[test]
    fn a_car_on_a_bridge_passes_over_a_car_on_the_road_below() {
        // Town04's road 39 crosses road 47 10.7 m up; cars on the two met.
        let crossing = |bridge_z: f32| {
            let mut ph = Physics::new(&Town::empty("bridge"));
            ph.add_vehicle(
                1,
                ActorKind::Vehicle,
                car(),
                Vec2::new(-10.0, 0.0),
                0.0,
                0.0,
            );
            ph.add_vehicle(
                2,
                ActorKind::Vehicle,
                car(),
                Vec2::ZERO,
                0.0,
                std::f32::consts::FRAC_PI_2,
            );
            ph.set_ground_z(1, bridge_z);
            assert_eq!(ph.ground_z(1), Some(bridge_z));
            let mut hit = false;
            for _ in 0..80 {
                let (p, yaw) = ph.pose_of(1).unwrap();
                hit |= ph
                    .move_actor(1, p + Vec2::new(0.25, 0.0), yaw)
                    .hit
                    .is_some();
                ph.end_tick();
            }
            hit
        };
        assert!(crossing(0.0), "on one level they meet");
        assert!(!crossing(10.7), "a bridge 10.7 m up passes over");
    }

    #[test]
    fn car_driven_into_another_car_stops_and_names_both() {
        let mut ph = Physics::new(&walled_town());
        ph.add_vehicle(0, ActorKind::Ego, car(), Vec2::new(-20.0, 0.0), 0.0, 0.0);
        ph.add_vehicle(3, ActorKind::Vehicle, car(), Vec2::new(-8.0, 0.5), 0.0, 0.2);
        let mut events = Vec::new();
        for _ in 0..100 {
            let (p, yaw) = ph.pose_of(0).unwrap();
            ph.move_actor(0, p + Vec2::new(0.3, 0.0), yaw);
            events.extend(ph.end_tick().iter().copied());
            assert!(!ph.overlapping(0, 3));
        }
        let first = events.first().expect("a contact");
        assert_eq!(
            first.a,
            Party::Actor {
                id: 0,
                kind: ActorKind::Ego
            }
        );
        assert_eq!(
            first.b,
            Party::Actor {
                id: 3,
                kind: ActorKind::Vehicle
            }
        );
        assert!(first.started);
        assert_eq!(events.iter().filter(|e| e.started).count(), 1);
        // The other car did not move.
        assert_eq!(ph.pose_of(3).unwrap(), (Vec2::new(-8.0, 0.5), 0.2));
        // The rapier world holds the town's walls, not the actors.
        assert_eq!(ph.world.bodies.len(), 0);
        assert_eq!(
            ph.world.colliders.len(),
            Physics::new(&walled_town()).world.colliders.len()
        );
    }

    #[test]
    fn pedestrians_pass_each_other_but_not_cars() {
        let mut ph = Physics::new(&walled_town());
        ph.add_pedestrian(5, Vec2::new(0.0, 0.0), 0.0);
        ph.add_pedestrian(6, Vec2::new(0.3, 0.0), 0.0);
        let out = ph.move_actor(5, Vec2::new(1.0, 0.0), 0.0);
        assert!(out.hit.is_none() && out.fraction == 1.0);
        ph.add_vehicle(1, ActorKind::Vehicle, car(), Vec2::new(5.0, 0.0), 0.0, 0.0);
        let out = ph.move_actor(5, Vec2::new(3.0, 0.0), 0.0);
        assert_eq!(
            out.hit,
            Some(Party::Actor {
                id: 1,
                kind: ActorKind::Vehicle
            })
        );
        assert!(out.position.x < 5.0 - 2.395 - 0.3 + 1e-3 && out.position.x > 2.2);
        assert!(!ph.overlapping(5, 1));
        assert!(!ph.pedestrian_fits(Vec2::new(5.0, 1.2), 0.1));
        assert!(ph.pedestrian_fits(Vec2::new(5.0, 3.0), 0.1));
    }
}
