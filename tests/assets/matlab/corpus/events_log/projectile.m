% a projectile with drag: when does it pass 10 m going up and down, and land?
g = 9.81; c = 0.05;
opts = odeset('Events', @(t, s) heights(t, s), 'RelTol', 1e-8, 'AbsTol', 1e-10);
s0 = [0; 0; 20; 25];      % x, y, vx, vy
[t, s, te, se, ie] = ode45(@(t, s) flight(t, s, g, c), [0 10], s0, opts);
plot(s(:,1), s(:,2)); hold on
plot(se(:,1), se(:,2), 'o')

function ds = flight(t, s, g, c)
v = sqrt(s(3)^2 + s(4)^2);
ds = [s(3); s(4); -c*v*s(3); -g - c*v*s(4)];
end

function [value, isterminal, direction] = heights(t, s)
value = [s(2) - 10; s(2)];
isterminal = [0; 1];
direction = [0; -1];
end
